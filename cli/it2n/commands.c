/*
 * The subcommands: load the dataset, call the core, print CSV. Every number
 * goes through it2n_format_val/it2n_format_par, so output is exact decimal
 * rounding of the fixed-point results.
 */
#include "cli.h"
#include "csv.h"
#include "out.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Big structs live here rather than on the stack. */
static it2n_csv g_csv;
static it2n_dataset g_ds;
static it2n_model g_mdl;

/* --kind bspline: data set and model in heap storage (up to 256 x 256
 * points), and the flags of whichever model was loaded. */
static it2n_bspline_data g_bds;
static it2n_bspline_model g_bmdl;
static it2n_bspline_rec *g_brec;
static uint32_t *g_blines;
static int32_t *g_bcoef;
static bool g_bspline;
static unsigned g_flags;

static void report(const it2n_csv_error *e, const char *name)
{
    char msg[512];
    it2n_csv_message(e, name, msg, sizeof(msg));
    fprintf(stderr, "%s\n", msg);
}

static const char *display_name(const cli_opts *o)
{
    return strcmp(o->path, "-") == 0 ? "<stdin>" : o->path;
}

int cli_load(const cli_opts *o, it2n_csv *csv, it2n_dataset *ds, it2n_model *mdl)
{
    const char *name = display_name(o);
    FILE *f = strcmp(o->path, "-") == 0 ? stdin : fopen(o->path, "rb");
    char chunk[4096];
    it2n_csv_error e;
    it2n_errinfo info;
    size_t got;
    int rc = IT2N_OK;

    if (f == NULL) {
        fprintf(stderr, "%s: cannot open: %s\n", name, strerror(errno));
        return CLI_EXIT_DATA;
    }
    it2n_csv_init(csv, o->flags);
    while (rc == IT2N_OK && (got = fread(chunk, 1, sizeof(chunk), f)) > 0) {
        rc = it2n_csv_feed(csv, chunk, got, &e);
    }
    if (rc == IT2N_OK && ferror(f)) {
        fprintf(stderr, "%s: read error: %s\n", name, strerror(errno));
        if (f != stdin) {
            fclose(f);
        }
        return CLI_EXIT_DATA;
    }
    if (f != stdin) {
        fclose(f);
    }
    if (rc == IT2N_OK) {
        rc = it2n_csv_finish(csv, ds, &e);
    }
    if (rc != IT2N_OK) {
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    it2n_model_init(mdl);
    rc = it2n_model_solve(mdl, ds, &info);
    if (rc != IT2N_OK) {
        it2n_csv_locate(csv, &info, &e);
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

/* cli_load for the B-spline kind into g_bds, g_bmdl. */
static int load_bspline(const cli_opts *o)
{
    const char *name = display_name(o);
    FILE *f;
    char chunk[4096];
    it2n_csv_error e;
    it2n_errinfo info;
    size_t got, words;
    int rc = IT2N_OK;

    g_brec = malloc(IT2N_CSV_BSPLINE_RECS * sizeof(*g_brec));
    g_blines = malloc(IT2N_CSV_BSPLINE_LINES * sizeof(*g_blines));
    if (g_brec == NULL || g_blines == NULL) {
        fprintf(stderr, "it2n: out of memory for a B-spline data set\n");
        return CLI_EXIT_DATA;
    }
    f = strcmp(o->path, "-") == 0 ? stdin : fopen(o->path, "rb");
    if (f == NULL) {
        fprintf(stderr, "%s: cannot open: %s\n", name, strerror(errno));
        return CLI_EXIT_DATA;
    }
    it2n_csv_init_bspline(&g_csv, g_brec, g_blines);
    while (rc == IT2N_OK && (got = fread(chunk, 1, sizeof(chunk), f)) > 0) {
        rc = it2n_csv_feed(&g_csv, chunk, got, &e);
    }
    if (rc == IT2N_OK && ferror(f)) {
        fprintf(stderr, "%s: read error: %s\n", name, strerror(errno));
        if (f != stdin) {
            fclose(f);
        }
        return CLI_EXIT_DATA;
    }
    if (f != stdin) {
        fclose(f);
    }
    if (rc == IT2N_OK) {
        rc = it2n_csv_finish_bspline(&g_csv, &g_bds, &e);
    }
    if (rc != IT2N_OK) {
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    words = IT2N_BSPLINE_MODEL_WORDS(g_bds.n, g_bds.m, g_bds.flags);
    g_bcoef = malloc(words * sizeof(*g_bcoef));
    if (g_bcoef == NULL) {
        fprintf(stderr, "it2n: out of memory for a B-spline model\n");
        return CLI_EXIT_DATA;
    }
    it2n_bspline_model_init(&g_bmdl, g_bcoef, words);
    rc = it2n_bspline_solve(&g_bmdl, &g_bds, &info);
    if (rc != IT2N_OK) {
        it2n_csv_locate(&g_csv, &info, &e);
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

static void free_bspline(void);

int cli_load_bspline(const cli_opts *o, const it2n_bspline_data **bds, const it2n_bspline_model **bmdl,
                     const it2n_csv **csv)
{
    int rc = load_bspline(o);
    *bds = &g_bds;
    *bmdl = &g_bmdl;
    *csv = &g_csv;
    return rc;
}

void cli_free_bspline(void)
{
    free_bspline();
}

static void free_bspline(void)
{
    free(g_brec);
    free(g_blines);
    free(g_bcoef);
    g_brec = NULL;
    g_blines = NULL;
    g_bcoef = NULL;
}

/* Read and validate the dataset, then solve it. */
static int load(const cli_opts *o)
{
    int rc;
    g_bspline = o->kind == CLI_KIND_BSPLINE;
    if (g_bspline) {
        rc = load_bspline(o);
        g_flags = g_bds.flags;
        return rc;
    }
    rc = cli_load(o, &g_csv, &g_ds, &g_mdl);
    g_flags = g_ds.flags;
    return rc;
}

static bool fp_in_model(unsigned fp)
{
    return (g_flags & IT2N_F_TYPE1) ? fp == IT2N_FP_D : fp < IT2N_FP_COUNT;
}

unsigned cli_surf_n(const cli_surface *s)
{
    return s->bsp != NULL ? s->bsp->n : s->bez->n;
}

unsigned cli_surf_m(const cli_surface *s)
{
    return s->bsp != NULL ? s->bsp->m : s->bez->m;
}

unsigned cli_surf_flags(const cli_surface *s)
{
    return s->bsp != NULL ? s->bsp->flags : s->bez->flags;
}

bool cli_surf_has_fp(const cli_surface *s, unsigned fp)
{
    return (cli_surf_flags(s) & IT2N_F_TYPE1) ? fp == IT2N_FP_D : fp < IT2N_FP_COUNT;
}

int cli_surf_eval(const cli_surface *s, it2n_par u, it2n_par w, it2n_point *pt, it2n_errinfo *err)
{
    return s->bsp != NULL ? it2n_bspline_eval(s->bsp, u, w, pt, err) : it2n_eval(s->bez, u, w, pt, err);
}

int cli_surf_locate(const cli_surface *s, it2n_val x, it2n_val y, it2n_locate_result *out, it2n_errinfo *err)
{
    return s->bsp != NULL ? it2n_bspline_locate(s->bsp, x, y, out, err) : it2n_locate(s->bez, x, y, out, err);
}

int cli_surf_sample(const cli_surface *s, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx,
                    it2n_errinfo *err)
{
    return s->bsp != NULL ? it2n_bspline_sample(s->bsp, rows, cols, cb, ctx, err)
                          : it2n_sample(s->bez, rows, cols, cb, ctx, err);
}

unsigned cli_surf_net_rows(const cli_surface *s)
{
    return s->bsp != NULL ? s->bsp->n + 3u : s->bez->n + 1u;
}

unsigned cli_surf_net_cols(const cli_surface *s)
{
    return s->bsp != NULL ? s->bsp->m + 3u : s->bez->m + 1u;
}

it2n_val cli_surf_coef(const cli_surface *s, unsigned r, unsigned c, unsigned fp, unsigned ch)
{
    return s->bsp != NULL ? it2n_bspline_coef(s->bsp, r, c, fp, ch) : it2n_model_ctrl(s->bez, r, c, fp, ch);
}

bool cli_surf_point(const cli_surface *s, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT])
{
    if (s->bsp != NULL) {
        const it2n_bspline_data *d = s->bds;
        unsigned nfp;
        if (d == NULL || i > d->n || j > d->m || !cli_surf_has_fp(s, fp)) {
            return false;
        }
        nfp = IT2N_BSPLINE_NFP(d->flags);
        if (!d->rec[((size_t)i * (d->m + 1u) + j) * nfp + (nfp == 1u ? 0u : fp)].present) {
            return false;
        }
        it2n_bspline_data_get(d, i, j, fp, v);
        return true;
    }
    if (s->ds == NULL || i > s->ds->n || j > s->ds->m || !s->ds->present[i][j]) {
        return false;
    }
    it2n_dataset_get(s->ds, i, j, fp, v);
    return true;
}

bool cli_fp_selected(const cli_opts *o, const cli_surface *mdl, unsigned fp)
{
    return cli_surf_has_fp(mdl, fp) &&
           (o->fpmask == 0u || (o->fpmask & (1u << fp)) != 0u);
}

void cli_fmt_val(char *buf, size_t size, it2n_val v, unsigned decimals)
{
    if (it2n_format_val(buf, size, v, decimals) < 0 && size > 1u) {
        buf[0] = '?'; /* cannot happen: 48 bytes fit any int64 */
        buf[1] = '\0';
    }
}

/* The rows' options and the loaded model's z and type (set by run). */
static cli_out g_out;

static int cmd_check(const cli_opts *o)
{
    unsigned n = g_bspline ? g_bds.n : g_ds.n, m = g_bspline ? g_bds.m : g_ds.m;
    bool t1 = (g_flags & IT2N_F_TYPE1) != 0u;
    printf("%s: ok: %ux%u grid (n=%u, m=%u), %s, coordinates %s, %s "
           "parameters%s\n",
           display_name(o), n + 1u, m + 1u, n, m,
           t1 ? "type-1 (footprint D)" : "type-2 (7 footprints)",
           g_out.z ? "x,y,z" : "x,y",
           (g_flags & IT2N_F_CHORD) ? "chord-length" : "uniform",
           g_bspline ? ", cubic B-spline (not-a-knot)" : "");
    return cli_finish_output("it2n");
}

/* B-spline coefficients c_{i,j}, i = -1..n+1, j = -1..m+1. */
static int cmd_solve_bspline(void)
{
    unsigned r, c, fp, ch;
    cli_put_header(&g_out, "i,j,footprint", "");
    for (r = 0; r <= g_bds.n + 2u; r++) {
        for (c = 0; c <= g_bds.m + 2u; c++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                if (!fp_in_model(fp)) {
                    continue;
                }
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    v[ch] = it2n_bspline_coef(&g_bmdl, r, c, fp, ch);
                }
                cli_put_net_row(&g_out, (int)r - 1, (int)c - 1, fp, v);
            }
        }
    }
    return cli_finish_output("it2n");
}

static int cmd_solve(void)
{
    unsigned i, j, fp;
    if (g_bspline) {
        return cmd_solve_bspline();
    }
    cli_put_header(&g_out, "i,j,footprint", "");
    for (i = 0; i <= g_ds.n; i++) {
        for (j = 0; j <= g_ds.m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!it2n_model_has_fp(&g_mdl, fp)) {
                    continue;
                }
                it2n_val v[IT2N_CH_COUNT];
                unsigned ch;
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    v[ch] = it2n_model_ctrl(&g_mdl, i, j, fp, ch);
                }
                cli_put_net_row(&g_out, (int)i, (int)j, fp, v);
            }
        }
    }
    return cli_finish_output("it2n");
}

static int core_fail(const char *what, int rc)
{
    fprintf(stderr, "it2n: %s failed: %s\n", what, it2n_strerror(rc));
    return CLI_EXIT_DATA;
}

static int cmd_eval(const cli_opts *o)
{
    it2n_point pt;
    size_t k;
    cli_put_header(&g_out, "u,w,footprint", ",out_of_range");
    for (k = 0; k < o->nat; k++) {
        int rc = g_bspline
                     ? it2n_bspline_eval(&g_bmdl, o->at[k].a, o->at[k].b, &pt, NULL)
                     : it2n_eval(&g_mdl, o->at[k].a, o->at[k].b, &pt, NULL);
        if (rc != IT2N_OK) {
            return core_fail("eval", rc);
        }
        cli_put_point(&g_out, o->at[k].a, o->at[k].b, &pt);
    }
    return cli_finish_output("it2n");
}

static int sample_row(void *ctx, unsigned r, unsigned c, it2n_par u,
                      it2n_par w, const it2n_point *pt)
{
    (void)r;
    (void)c;
    (void)ctx;
    cli_put_point(&g_out, u, w, pt);
    return ferror(stdout) ? 1 : 0;
}

static int cmd_sample(const cli_opts *o)
{
    int rc;
    cli_put_header(&g_out, "u,w,footprint", ",out_of_range");
    rc = g_bspline ? it2n_bspline_sample(&g_bmdl, o->rows, o->cols, sample_row,
                                         (void *)o, NULL)
                   : it2n_sample(&g_mdl, o->rows, o->cols, sample_row,
                                 (void *)o, NULL);
    if (rc < 0) {
        return core_fail("sample", rc);
    }
    return cli_finish_output("it2n");
}

static int cmd_deriv(const cli_opts *o)
{
    it2n_point du, dw;
    size_t k;
    unsigned fp;
    cli_put_header(&g_out, "u,w,footprint,wrt", "");
    for (k = 0; k < o->nat; k++) {
        int rc = g_bspline ? it2n_bspline_deriv(&g_bmdl, o->at[k].a, o->at[k].b,
                                                &du, &dw, NULL)
                           : it2n_deriv(&g_mdl, o->at[k].a, o->at[k].b, &du,
                                        &dw, NULL);
        if (rc != IT2N_OK) {
            return core_fail("deriv", rc);
        }
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            int d;
            if (!fp_in_model(fp)) {
                continue;
            }
            for (d = 0; d < 2; d++) {
                cli_put_par(o->at[k].a, o->decimals);
                putchar(',');
                cli_put_par(o->at[k].b, o->decimals);
                printf(",%s,%s", it2n_fp_name(fp), d == 0 ? "u" : "w");
                cli_put_channels(&g_out, d == 0 ? du.v[fp] : dw.v[fp]);
                putchar('\n');
            }
        }
    }
    return cli_finish_output("it2n");
}

static int cmd_locate(const cli_opts *o)
{
    static const char *const status[3] = {"inside", "outside", "noconv"};
    it2n_locate_result res;
    size_t k;
    unsigned fp;
    printf("x,y,footprint,u,w%s,T,I,F,status\n", g_out.z ? ",z" : "");
    for (k = 0; k < o->nat; k++) {
        int rc = g_bspline ? it2n_bspline_locate(&g_bmdl, o->at[k].a, o->at[k].b,
                                                 &res, NULL)
                           : it2n_locate(&g_mdl, o->at[k].a, o->at[k].b, &res, NULL);
        if (rc != IT2N_OK) {
            return core_fail("locate", rc);
        }
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            const it2n_locate_fp *r = &res.fp[fp];
            const it2n_par uw[2] = {r->u, r->w};
            if (!fp_in_model(fp)) {
                continue;
            }
            cli_put_locate_row(&g_out, o->at[k].a, o->at[k].b, fp, uw, r->v,
                               r->status < 3u ? status[r->status] : "?");
        }
    }
    return cli_finish_output("it2n");
}

typedef struct mesh_ctx {
    cli_mesh *mesh;
} mesh_ctx;

static int mesh_row(void *ctx, unsigned r, unsigned c, it2n_par u,
                    it2n_par w, const it2n_point *pt)
{
    cli_mesh *m = ((mesh_ctx *)ctx)->mesh;
    memcpy(&m->v[((size_t)r * m->cols + c) * IT2N_FP_COUNT * IT2N_CH_COUNT],
           pt->v, sizeof(pt->v));
    m->u[r] = u;
    m->w[c] = w;
    return 0;
}

int cli_mesh_sample(cli_mesh *mesh, const cli_surface *mdl, unsigned rows,
                    unsigned cols)
{
    size_t nodes = (size_t)rows * cols;
    mesh_ctx ctx;
    int rc;
    mesh->rows = rows;
    mesh->cols = cols;
    mesh->v = malloc(nodes * IT2N_FP_COUNT * IT2N_CH_COUNT * sizeof(it2n_val));
    mesh->u = malloc(rows * sizeof(it2n_par));
    mesh->w = malloc(cols * sizeof(it2n_par));
    if (mesh->v == NULL || mesh->u == NULL || mesh->w == NULL) {
        cli_mesh_free(mesh);
        fprintf(stderr, "it2n: out of memory for a %ux%u grid\n", rows, cols);
        return CLI_EXIT_DATA;
    }
    ctx.mesh = mesh;
    rc = cli_surf_sample(mdl, rows, cols, mesh_row, &ctx, NULL);
    if (rc != IT2N_OK) {
        cli_mesh_free(mesh);
        return core_fail("sample", rc);
    }
    return CLI_EXIT_OK;
}

void cli_mesh_free(cli_mesh *mesh)
{
    free(mesh->v);
    free(mesh->u);
    free(mesh->w);
    mesh->v = NULL;
    mesh->u = mesh->w = NULL;
}

static int run(const cli_opts *o);

int cli_run(const cli_opts *o)
{
    int rc = run(o);
    free_bspline();
    return rc;
}

static int run(const cli_opts *o)
{
    unsigned fp;
    int rc = load(o);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    cli_out_init(&g_out, g_flags, o->decimals, o->fpmask, o->summary);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if ((o->fpmask & (1u << fp)) && !fp_in_model(fp)) {
            fprintf(stderr,
                    "%s: --footprint %s: not in this type-1 model (footprint "
                    "D only)\n",
                    display_name(o), it2n_fp_name(fp));
            return CLI_EXIT_DATA;
        }
    }
    if (strcmp(o->cmd, "plot") == 0 || strcmp(o->cmd, "export") == 0) {
        cli_surface sf;
        memset(&sf, 0, sizeof(sf));
        if (g_bspline) {
            sf.bsp = &g_bmdl;
            sf.bds = &g_bds;
        } else {
            sf.bez = &g_mdl;
            sf.ds = &g_ds;
        }
        return strcmp(o->cmd, "plot") == 0 ? cli_plot(o, &sf) : cli_export(o, &sf);
    }
    if (strcmp(o->cmd, "check") == 0) {
        return cmd_check(o);
    }
    if (strcmp(o->cmd, "solve") == 0) {
        return cmd_solve();
    }
    if (strcmp(o->cmd, "eval") == 0) {
        return cmd_eval(o);
    }
    if (strcmp(o->cmd, "sample") == 0) {
        return cmd_sample(o);
    }
    if (strcmp(o->cmd, "deriv") == 0) {
        return cmd_deriv(o);
    }
    return cmd_locate(o);
}
