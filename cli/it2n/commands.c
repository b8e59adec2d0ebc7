/*
 * The subcommands: load the dataset, call the core, print CSV. Every number
 * goes through it2n_format_val/it2n_format_par, so output is exact decimal
 * rounding of the fixed-point results.
 */
#include "commands.h"
#include "csv.h"
#include "out.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Big structs live here rather than on the stack. */
static cli_csv_reader g_csv;
static it2n_dataset g_ds;
static it2n_model g_mdl;

/* --kind bspline: data set and model (cli_load_bspline's heap storage),
 * and the flags of whichever model was loaded. */
static const it2n_bspline_data *g_bds;
static const it2n_bspline_model *g_bmdl;
static bool g_bspline;
static unsigned g_flags;

/* The rows' options and the loaded model's z and type (set by run). */
static cli_out g_out;

static const char *display_name(const cli_opts *o)
{
    return cli_display_name(o->path);
}

static int core_fail(const char *what, int rc)
{
    fprintf(stderr, "it2n: %s failed: %s\n", what, it2n_strerror(rc));
    return CLI_EXIT_DATA;
}

/* Read and validate the dataset, then solve it. */
static int load(const cli_opts *o)
{
    int rc;
    g_bspline = o->kind == CLI_KIND_BSPLINE;
    if (g_bspline) {
        const cli_csv_reader *csv;
        rc = cli_load_bspline(o, &g_bds, &g_bmdl, &csv);
        g_flags = g_bds->flags;
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

static int cmd_check(const cli_opts *o)
{
    unsigned n = g_bspline ? g_bds->n : g_ds.n, m = g_bspline ? g_bds->m : g_ds.m;
    bool t1 = (g_flags & IT2N_F_TYPE1) != 0u;
    printf("%s: ok: %ux%u grid (n=%u, m=%u), %s, coordinates %s, %s "
           "parameters%s\n",
           display_name(o), n + 1u, m + 1u, n, m, t1 ? "type-1 (footprint D)" : "type-2 (7 footprints)",
           g_out.z ? "x,y,z" : "x,y", (g_flags & IT2N_F_CHORD) ? "chord-length" : "uniform",
           g_bspline ? ", cubic B-spline (not-a-knot)" : "");
    return cli_finish_output("it2n");
}

/* B-spline coefficients c_{i,j}, i = -1..n+1, j = -1..m+1. */
static int cmd_solve_bspline(void)
{
    unsigned r, c, fp, ch;
    cli_put_header(&g_out, "i,j,footprint", "");
    for (r = 0; r <= g_bds->n + 2u; r++) {
        for (c = 0; c <= g_bds->m + 2u; c++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                if (!fp_in_model(fp)) {
                    continue;
                }
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    v[ch] = it2n_bspline_coef(g_bmdl, r, c, fp, ch);
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

static int cmd_eval(const cli_opts *o)
{
    it2n_point pt;
    size_t k;
    cli_put_header(&g_out, "u,w,footprint", ",out_of_range");
    for (k = 0; k < o->nat; k++) {
        int rc = g_bspline ? it2n_bspline_eval(g_bmdl, o->at[k].a, o->at[k].b, &pt, NULL)
                           : it2n_eval(&g_mdl, o->at[k].a, o->at[k].b, &pt, NULL);
        if (rc != IT2N_OK) {
            return core_fail("eval", rc);
        }
        cli_put_point(&g_out, o->at[k].a, o->at[k].b, &pt);
    }
    return cli_finish_output("it2n");
}

static int cmd_sample(const cli_opts *o)
{
    int rc;
    cli_put_header(&g_out, "u,w,footprint", ",out_of_range");
    rc = g_bspline ? it2n_bspline_sample(g_bmdl, o->rows, o->cols, cli_put_sample_row, &g_out, NULL)
                   : it2n_sample(&g_mdl, o->rows, o->cols, cli_put_sample_row, &g_out, NULL);
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
        int rc = g_bspline ? it2n_bspline_deriv(g_bmdl, o->at[k].a, o->at[k].b, &du, &dw, NULL)
                           : it2n_deriv(&g_mdl, o->at[k].a, o->at[k].b, &du, &dw, NULL);
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
        int rc = g_bspline ? it2n_bspline_locate(g_bmdl, o->at[k].a, o->at[k].b, &res, NULL)
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
            cli_put_locate_row(&g_out, o->at[k].a, o->at[k].b, fp, uw, r->v, r->status < 3u ? status[r->status] : "?");
        }
    }
    return cli_finish_output("it2n");
}

static int run(const cli_opts *o);

int cmd_run(const cli_opts *o)
{
    int rc = run(o);
    cli_free_bspline();
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
            sf.bsp = g_bmdl;
            sf.data = cli_data_bspline(g_bds);
        } else {
            sf.bez = &g_mdl;
            sf.data = cli_data_bezier(&g_ds);
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
