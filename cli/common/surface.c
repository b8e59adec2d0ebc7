/*
 * A solved model of either kind behind one interface (cli_surface), and
 * its samples held for plot and export, for both programs.
 */
#include "cli.h"
#include "csv.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

int cli_surf_sample(const cli_surface *s, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx, it2n_errinfo *err)
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
    if (!cli_surf_has_fp(s, fp) || !cli_data_has(&s->data, i, j, fp)) {
        return false;
    }
    cli_data_get(&s->data, i, j, fp, v);
    return true;
}

bool cli_fp_selected(const cli_opts *o, const cli_surface *mdl, unsigned fp)
{
    return cli_surf_has_fp(mdl, fp) && (o->fpmask == 0u || (o->fpmask & (1u << fp)) != 0u);
}

void cli_fmt_val(char *buf, size_t size, it2n_val v, unsigned decimals)
{
    if (it2n_format_val(buf, size, v, decimals) < 0 && size > 1u) {
        buf[0] = '?'; /* cannot happen: 48 bytes fit any int64 */
        buf[1] = '\0';
    }
}

static int core_fail(const char *what, int rc)
{
    fprintf(stderr, "it2n: %s failed: %s\n", what, it2n_strerror(rc));
    return CLI_EXIT_DATA;
}

typedef struct mesh_ctx {
    cli_mesh *mesh;
} mesh_ctx;

static int mesh_row(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w, const it2n_point *pt)
{
    cli_mesh *m = ((mesh_ctx *)ctx)->mesh;
    memcpy(&m->v[((size_t)r * m->cols + c) * IT2N_FP_COUNT * IT2N_CH_COUNT], pt->v, sizeof(pt->v));
    m->u[r] = u;
    m->w[c] = w;
    return 0;
}

int cli_mesh_sample(cli_mesh *mesh, const cli_surface *mdl, unsigned rows, unsigned cols)
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
