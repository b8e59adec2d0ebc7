/*
 * it2n export: the sampled surfaces as meshes, one object per footprint and
 * membership, vertices (x, y, membership) in exact decimal text.
 *   vtk  VTK legacy ASCII POLYDATA (ParaView): quads, point data value, u,
 *        w (and z), cell data footprint_id and membership_id
 *   obj  Wavefront OBJ (MeshLab): "o FP_M" / "g FP_M" per object, quads
 *   csv  one row per vertex
 */
#include "cli.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

static const char *const memb_name[3] = {"T", "I", "F"};

typedef struct exp_ctx {
    const cli_opts *o;
    const cli_surface *mdl;
    const cli_mesh *mesh;
    FILE *f;
    bool z;
    unsigned fps[IT2N_FP_COUNT], nfp; /* selected footprints, in order */
    unsigned mem[3], nmem;            /* selected memberships (0..2)   */
} exp_ctx;

static void put(exp_ctx *x, it2n_val v)
{
    char buf[48];
    cli_fmt_val(buf, sizeof(buf), v, x->o->decimals);
    fputs(buf, x->f);
}

static void put_par(exp_ctx *x, it2n_par p)
{
    char buf[48];
    unsigned d = x->o->decimals;
    if (it2n_format_par(buf, sizeof(buf), p, d < CLI_PAR_DECIMALS ? CLI_PAR_DECIMALS : d) < 0) {
        buf[0] = '?';
        buf[1] = '\0';
    }
    fputs(buf, x->f);
}

/* "x y value" of node (r, c) of footprint fp, membership k. */
static void put_vertex(exp_ctx *x, unsigned r, unsigned c, unsigned fp, unsigned k, const char *sep)
{
    put(x, cli_mesh_at(x->mesh, r, c, fp, IT2N_CH_X));
    fputs(sep, x->f);
    put(x, cli_mesh_at(x->mesh, r, c, fp, IT2N_CH_Y));
    fputs(sep, x->f);
    put(x, cli_mesh_at(x->mesh, r, c, fp, IT2N_CH_T + k));
}

/* Quads of one object whose first vertex has index base. */
static void put_quads(exp_ctx *x, const char *lead, size_t base)
{
    unsigned r, c, cols = x->mesh->cols;
    for (r = 0; r + 1u < x->mesh->rows; r++) {
        for (c = 0; c + 1u < cols; c++) {
            size_t a = base + (size_t)r * cols + c;
            fprintf(x->f, "%s%zu %zu %zu %zu\n", lead, a, a + cols, a + cols + 1u, a + 1u);
        }
    }
}

static void export_vtk(exp_ctx *x)
{
    const cli_mesh *m = x->mesh;
    size_t per = (size_t)m->rows * m->cols;
    size_t quads = (size_t)(m->rows - 1u) * (m->cols - 1u);
    size_t nobj = (size_t)x->nfp * x->nmem;
    unsigned a, b, r, c;
    int arr;

    fprintf(x->f,
            "# vtk DataFile Version 3.0\n"
            "it2n export: %ux%u grid, %zu objects (cell data footprint_id "
            "0..6 = LL,LR,L,D,R,RL,RR; membership_id 0..2 = T,I,F)\n"
            "ASCII\nDATASET POLYDATA\nPOINTS %zu double\n",
            m->rows, m->cols, nobj, nobj * per);
    for (a = 0; a < x->nfp; a++) {
        for (b = 0; b < x->nmem; b++) {
            for (r = 0; r < m->rows; r++) {
                for (c = 0; c < m->cols; c++) {
                    put_vertex(x, r, c, x->fps[a], x->mem[b], " ");
                    fputc('\n', x->f);
                }
            }
        }
    }
    fprintf(x->f, "POLYGONS %zu %zu\n", nobj * quads, nobj * quads * 5u);
    for (a = 0; a < nobj; a++) {
        put_quads(x, "4 ", a * per);
    }
    fprintf(x->f, "CELL_DATA %zu\n", nobj * quads);
    for (arr = 0; arr < 2; arr++) {
        fprintf(x->f, "SCALARS %s int 1\nLOOKUP_TABLE default\n", arr == 0 ? "footprint_id" : "membership_id");
        for (a = 0; a < x->nfp; a++) {
            for (b = 0; b < x->nmem; b++) {
                size_t q;
                for (q = 0; q < quads; q++) {
                    fprintf(x->f, "%u\n", arr == 0 ? x->fps[a] : x->mem[b]);
                }
            }
        }
    }
    fprintf(x->f, "POINT_DATA %zu\n", nobj * per);
    for (arr = 0; arr < 4; arr++) {
        static const char *const names[4] = {"value", "u", "w", "z"};
        if (arr == 3 && !x->z) {
            break;
        }
        fprintf(x->f, "SCALARS %s double 1\nLOOKUP_TABLE default\n", names[arr]);
        for (a = 0; a < x->nfp; a++) {
            for (b = 0; b < x->nmem; b++) {
                for (r = 0; r < m->rows; r++) {
                    for (c = 0; c < m->cols; c++) {
                        if (arr == 0) {
                            put(x, cli_mesh_at(m, r, c, x->fps[a], IT2N_CH_T + x->mem[b]));
                        } else if (arr == 1) {
                            put_par(x, m->u[r]);
                        } else if (arr == 2) {
                            put_par(x, m->w[c]);
                        } else {
                            put(x, cli_mesh_at(m, r, c, x->fps[a], IT2N_CH_Z));
                        }
                        fputc('\n', x->f);
                    }
                }
            }
        }
    }
}

static void export_obj(exp_ctx *x)
{
    const cli_mesh *m = x->mesh;
    size_t per = (size_t)m->rows * m->cols, base = 1u;
    unsigned a, b, r, c;
    fprintf(x->f,
            "# it2n export: %ux%u grid, vertices (x, y, membership), one "
            "object per footprint and membership\n",
            m->rows, m->cols);
    for (a = 0; a < x->nfp; a++) {
        for (b = 0; b < x->nmem; b++) {
            const char *fpn = it2n_fp_name(x->fps[a]);
            const char *mn = memb_name[x->mem[b]];
            fprintf(x->f, "o %s_%s\ng %s_%s\n", fpn, mn, fpn, mn);
            for (r = 0; r < m->rows; r++) {
                for (c = 0; c < m->cols; c++) {
                    fputs("v ", x->f);
                    put_vertex(x, r, c, x->fps[a], x->mem[b], " ");
                    fputc('\n', x->f);
                }
            }
            put_quads(x, "f ", base);
            base += per;
        }
    }
}

static void export_csv(exp_ctx *x)
{
    const cli_mesh *m = x->mesh;
    unsigned a, b, r, c;
    fprintf(x->f, "object,footprint,membership,r,c,u,w,x,y%s,value\n", x->z ? ",z" : "");
    for (a = 0; a < x->nfp; a++) {
        for (b = 0; b < x->nmem; b++) {
            const char *fpn = it2n_fp_name(x->fps[a]);
            const char *mn = memb_name[x->mem[b]];
            for (r = 0; r < m->rows; r++) {
                for (c = 0; c < m->cols; c++) {
                    fprintf(x->f, "%s_%s,%s,%s,%u,%u,", fpn, mn, fpn, mn, r, c);
                    put_par(x, m->u[r]);
                    fputc(',', x->f);
                    put_par(x, m->w[c]);
                    fputc(',', x->f);
                    put(x, cli_mesh_at(m, r, c, x->fps[a], IT2N_CH_X));
                    fputc(',', x->f);
                    put(x, cli_mesh_at(m, r, c, x->fps[a], IT2N_CH_Y));
                    if (x->z) {
                        fputc(',', x->f);
                        put(x, cli_mesh_at(m, r, c, x->fps[a], IT2N_CH_Z));
                    }
                    fputc(',', x->f);
                    put(x, cli_mesh_at(m, r, c, x->fps[a], IT2N_CH_T + x->mem[b]));
                    fputc('\n', x->f);
                }
            }
        }
    }
}

int cli_export(const cli_opts *o, const cli_surface *mdl)
{
    cli_mesh mesh;
    exp_ctx x;
    unsigned fp, k;
    bool to_stdout = o->output == NULL || strcmp(o->output, "-") == 0;
    int rc;

    memset(&x, 0, sizeof(x));
    x.o = o;
    x.mdl = mdl;
    x.z = (cli_surf_flags(mdl) & IT2N_F_Z) != 0u;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (cli_fp_selected(o, mdl, fp)) {
            x.fps[x.nfp++] = fp;
        }
    }
    for (k = 0; k < 3u; k++) {
        if (o->membership < 0 || (unsigned)o->membership == k) {
            x.mem[x.nmem++] = k;
        }
    }
    rc = cli_mesh_sample(&mesh, mdl, o->rows, o->cols);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    x.mesh = &mesh;
    x.f = to_stdout ? stdout : fopen(o->output, "w");
    if (x.f == NULL) {
        fprintf(stderr, "%s: cannot create: %s\n", o->output, strerror(errno));
        cli_mesh_free(&mesh);
        return CLI_EXIT_DATA;
    }
    if (o->format == CLI_FMT_VTK) {
        export_vtk(&x);
    } else if (o->format == CLI_FMT_OBJ) {
        export_obj(&x);
    } else {
        export_csv(&x);
    }
    cli_mesh_free(&mesh);
    if (fflush(x.f) != 0 || ferror(x.f)) {
        fprintf(stderr, "%s: write error: %s\n", to_stdout ? "it2n" : o->output, strerror(errno));
        if (!to_stdout) {
            fclose(x.f);
        }
        return CLI_EXIT_DATA;
    }
    if (!to_stdout && fclose(x.f) != 0) {
        fprintf(stderr, "%s: write error: %s\n", o->output, strerror(errno));
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}
