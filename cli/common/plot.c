/*
 * it2n plot: writes the sampled surfaces, control nets (or the interval band
 * over (x, y)) and a gnuplot script into a private temporary directory, runs
 * gnuplot on it and removes the directory. Every number is the core's
 * fixed-point result in exact decimal text; the CLI adds no maths beyond
 * minima, maxima and differences of those integers.
 */
#include "cli.h"

#include <errno.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

static const char *const memb_long[3] = {"truth", "indeterminacy", "falsity"};
static const char *const memb_short[3] = {"T", "I", "F"};

/* Footprint classes: how a surface is drawn. */
enum { CLS_UPPER = 0, CLS_LOWER, CLS_INNER, CLS_TYPE1, CLS_COUNT };
static const char *const cls_name[CLS_COUNT] = {"upper (LL, RR)", "lower (LR, RL)", "inner (L, R)", "type-1 D"};
static const char *const cls_dash[CLS_COUNT] = {"1", "2", "3", "1"};
static const char *const cls_width[CLS_COUNT] = {"1.2", "1.2", "1.2", "2.5"};
/* Paper colours: truth green, indeterminacy blue, falsity red; one shade
 * per class (upper darkest, lower lightest). */
static const char *const colour[3][CLS_COUNT] = {{"#00441b", "#74c476", "#238b45", "#1a9641"},
                                                 {"#08306b", "#6baed6", "#2171b5", "#2166ac"},
                                                 {"#67000d", "#fb6a4a", "#cb181d", "#d7191c"}};

static unsigned fp_class(unsigned fp)
{
    switch (fp) {
    case IT2N_FP_LL:
    case IT2N_FP_RR: return CLS_UPPER;
    case IT2N_FP_LR:
    case IT2N_FP_RL: return CLS_LOWER;
    case IT2N_FP_L:
    case IT2N_FP_R: return CLS_INNER;
    default: return CLS_TYPE1;
    }
}

/* A gnuplot single-quoted string: ' doubled. */
static void put_quoted(FILE *f, const char *s)
{
    fputc('\'', f);
    for (; *s; s++) {
        if (*s == '\'') {
            fputc('\'', f);
        }
        fputc(*s, f);
    }
    fputc('\'', f);
}

static void put_val(FILE *f, it2n_val v, unsigned decimals)
{
    char buf[48];
    cli_fmt_val(buf, sizeof(buf), v, decimals);
    fputs(buf, f);
}

typedef struct tmpfiles {
    char dir[512];
    char path[5][600];
    unsigned n;
} tmpfiles;

static FILE *tmp_open(tmpfiles *t, const char *name)
{
    FILE *f;
    char dir[sizeof(t->dir)];
    memcpy(dir, t->dir, sizeof(dir));
    snprintf(t->path[t->n], sizeof(t->path[0]), "%s/%s", dir, name);
    f = fopen(t->path[t->n], "w");
    if (f != NULL) {
        t->n++;
    } else {
        fprintf(stderr, "it2n: cannot create %s: %s\n", t->path[t->n], strerror(errno));
    }
    return f;
}

static int tmp_close(FILE *f)
{
    bool bad = fflush(f) != 0 || ferror(f);
    if (fclose(f) != 0 || bad) {
        fprintf(stderr, "it2n: cannot write temporary file: %s\n", strerror(errno));
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

static void tmp_remove(tmpfiles *t)
{
    unsigned k;
    for (k = 0; k < t->n; k++) {
        unlink(t->path[k]);
    }
    if (t->dir[0]) {
        rmdir(t->dir);
    }
}

static void plot_size(const cli_opts *o, unsigned *w, unsigned *h);

static void put_terminal(FILE *g, const cli_opts *o)
{
    const char *dot = strrchr(o->output, '.');
    bool svg = dot != NULL && strcasecmp(dot, ".svg") == 0;
    unsigned w, h;
    plot_size(o, &w, &h);
    fprintf(g,
            "set terminal %s size %u,%u noenhanced font 'sans,%u' "
            "background '#ffffff'\n",
            svg ? "svg" : "pngcairo", w, h, w >= 1400u && h >= 900u ? 12u : 10u);
    fputs("set output ", g);
    put_quoted(g, o->output);
    fputs("\nset encoding utf8\n", g);
}

static const char *base_name(const cli_opts *o)
{
    const char *s;
    if (strcmp(o->path, "-") == 0) {
        return "<stdin>";
    }
    s = strrchr(o->path, '/');
    return s ? s + 1 : o->path;
}

/* Membership range per channel T, I, F over what is drawn: the z axis is
 * scaled to the surfaces and data points (and the nets when drawn), not to
 * the control nets alone, which overshoot the surfaces by far. */
typedef struct zspan {
    it2n_val lo[3], hi[3];
    bool any[3];
} zspan;

static void zspan_add(zspan *z, unsigned k, it2n_val v)
{
    if (!z->any[k] || v < z->lo[k]) {
        z->lo[k] = v;
    }
    if (!z->any[k] || v > z->hi[k]) {
        z->hi[k] = v;
    }
    z->any[k] = true;
}

/* One row "x y T I F" (z left out: the plot is over (x, y)). */
static void put_row(FILE *f, const it2n_val v[IT2N_CH_COUNT], unsigned decimals)
{
    unsigned ch;
    for (ch = IT2N_CH_X; ch < IT2N_CH_COUNT; ch++) {
        if (ch == IT2N_CH_Z) {
            continue;
        }
        if (ch != IT2N_CH_X) {
            fputc(' ', f);
        }
        put_val(f, v[ch], decimals);
    }
    fputc('\n', f);
}

/* The data points of footprint fp: the data set's where it has them (it2n),
 * else the surfaces at the parameter nodes, where they interpolate the data
 * (it2nctl's live model; uniform parameters only). Returns how many. */
static unsigned write_points(FILE *f, const cli_surface *mdl, unsigned fp, unsigned decimals, zspan *z)
{
    unsigned i, j, k, count = 0, n = cli_surf_n(mdl), m = cli_surf_m(mdl);
    it2n_val v[IT2N_CH_COUNT];
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= m; j++) {
            if (!cli_surf_point(mdl, i, j, fp, v)) {
                it2n_point pt;
                if ((cli_surf_flags(mdl) & IT2N_F_CHORD) ||
                    cli_surf_eval(mdl, (it2n_par)(((uint64_t)i << 32) / n), (it2n_par)(((uint64_t)j << 32) / m), &pt,
                                  NULL) != IT2N_OK) {
                    continue;
                }
                memcpy(v, pt.v[fp], sizeof(v));
            }
            put_row(f, v, decimals);
            for (k = 0; k < 3u; k++) {
                zspan_add(z, k, v[IT2N_CH_T + k]);
            }
            count++;
        }
    }
    return count;
}

/* Surfaces, data points and control nets: data blocks, one per selected
 * footprint in each file. */
static int write_surfaces(const cli_opts *o, const cli_surface *mdl, tmpfiles *t, unsigned fps[], unsigned *nfp,
                          zspan *z, unsigned *npoints)
{
    cli_mesh mesh;
    FILE *s, *n, *p;
    unsigned a, fp, r, c, k;
    int rc = cli_mesh_sample(&mesh, mdl, o->rows, o->cols);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    *nfp = 0;
    *npoints = 0;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (cli_fp_selected(o, mdl, fp)) {
            fps[(*nfp)++] = fp;
        }
    }
    s = tmp_open(t, "surfaces.dat");
    n = s ? tmp_open(t, "nets.dat") : NULL;
    p = n ? tmp_open(t, "points.dat") : NULL;
    if (s == NULL || n == NULL || p == NULL) {
        if (s) {
            fclose(s);
        }
        if (n) {
            fclose(n);
        }
        cli_mesh_free(&mesh);
        return CLI_EXIT_DATA;
    }
    for (a = 0; a < *nfp; a++) {
        it2n_val v[IT2N_CH_COUNT];
        fp = fps[a];
        fprintf(s, "# footprint %s: x y T I F, %u rows of %u samples\n", it2n_fp_name(fp), mesh.rows, mesh.cols);
        for (r = 0; r < mesh.rows; r++) {
            for (c = 0; c < mesh.cols; c++) {
                for (k = 0; k < IT2N_CH_COUNT; k++) {
                    v[k] = cli_mesh_at(&mesh, r, c, fp, k);
                }
                put_row(s, v, o->decimals);
                for (k = 0; k < 3u; k++) {
                    zspan_add(z, k, v[IT2N_CH_T + k]);
                }
            }
            fputc('\n', s);
        }
        fputs("\n", s);
        fprintf(p, "# data points %s: x y T I F\n", it2n_fp_name(fp));
        *npoints += write_points(p, mdl, fp, o->decimals, z);
        fputs("\n\n", p);
        fprintf(n, "# control net %s: x y T I F\n", it2n_fp_name(fp));
        for (r = 0; r < cli_surf_net_rows(mdl); r++) {
            for (c = 0; c < cli_surf_net_cols(mdl); c++) {
                for (k = 0; k < IT2N_CH_COUNT; k++) {
                    v[k] = cli_surf_coef(mdl, r, c, fp, k);
                }
                put_row(n, v, o->decimals);
                for (k = 0; o->nets && k < 3u; k++) {
                    zspan_add(z, k, v[IT2N_CH_T + k]);
                }
            }
            fputc('\n', n);
        }
        fputs("\n", n);
    }
    cli_mesh_free(&mesh);
    rc = tmp_close(s);
    if (tmp_close(n) != CLI_EXIT_OK || tmp_close(p) != CLI_EXIT_OK) {
        rc = CLI_EXIT_DATA;
    }
    return rc;
}

/* set zrange: the span of channel k with a 6 % margin each side (0.05 for
 * a flat surface), so nothing drawn touches the box. */
static void put_zrange(FILE *g, const zspan *z, unsigned k, unsigned decimals)
{
    it2n_val lo = z->any[k] ? z->lo[k] : 0, hi = z->any[k] ? z->hi[k] : 0;
    it2n_val pad = (hi - lo) / 16;
    if (pad < IT2N_VAL_ONE / 20) {
        pad = IT2N_VAL_ONE / 20;
    }
    fputs("set zrange [", g);
    put_val(g, lo - pad, decimals);
    fputc(':', g);
    put_val(g, hi + pad, decimals);
    fputs("]\n", g);
}

/* One 3-D panel: membership k of every selected footprint, hidden lines
 * removed (hidden3d), data points and nets drawn on top. */
static void put_panel(FILE *g, const cli_opts *o, const cli_surface *mdl, const unsigned fps[], unsigned nfp,
                      unsigned k, const zspan *z, unsigned npoints, const char *key)
{
    bool cls_seen[CLS_COUNT] = {false, false, false, false};
    bool type1 = (cli_surf_flags(mdl) & IT2N_F_TYPE1) != 0u;
    unsigned a;
    fprintf(g, "set zlabel '%s %s' rotate parallel\n", memb_long[k], memb_short[k]);
    put_zrange(g, z, k, 6u);
    fprintf(g, "set key %s\nsplot \\\n", key);
    for (a = 0; a < nfp; a++) {
        unsigned cl = fp_class(fps[a]);
        fprintf(g,
                "%s  surf index %u using 1:2:%u with lines lc rgb '%s' "
                "dt %s lw %s ",
                a == 0u ? "" : ", \\\n", a, 3u + k, colour[k][cl], cls_dash[cl], cls_width[cl]);
        if (cls_seen[cl]) {
            fputs("notitle", g);
        } else {
            fprintf(g, "title '%s'", cl == CLS_TYPE1 && !type1 ? "mean (D)" : cls_name[cl]);
            cls_seen[cl] = true;
        }
    }
    if (npoints > 0u) {
        for (a = 0; a < nfp; a++) {
            fprintf(g,
                    ", \\\n  pts index %u using 1:2:%u with points "
                    "nohidden3d pt 7 ps 0.7 lc rgb '#000000' %s",
                    a, 3u + k, a == 0u ? "title 'data points'" : "notitle");
        }
    }
    if (o->nets) {
        for (a = 0; a < nfp; a++) {
            unsigned cl = fp_class(fps[a]);
            /* Nets half transparent (#AARRGGBB): the surfaces stay
             * readable through them. */
            fprintf(g,
                    ", \\\n  nets index %u using 1:2:%u with linespoints "
                    "nohidden3d lc rgb '#80%s' dt 1 lw 0.6 pt 6 ps 0.5 %s",
                    a, 3u + k, colour[k][cl] + 1, a == 0u ? "title 'control nets'" : "notitle");
        }
    }
    fputs("\n", g);
}

/* The default image size by figure: three panels side by side need width. */
static void plot_size(const cli_opts *o, unsigned *w, unsigned *h)
{
    if (o->width != 0u) {
        *w = o->width;
        *h = o->height;
    } else if (o->interval) {
        *w = 1000u;
        *h = 500u;
    } else if (o->membership < 0) {
        *w = 1500u;
        *h = 600u;
    } else {
        *w = 900u;
        *h = 700u;
    }
}

static int script_surfaces(const cli_opts *o, const cli_surface *mdl, tmpfiles *t)
{
    unsigned fps[IT2N_FP_COUNT], nfp, k, npoints;
    zspan z;
    char title[512];
    FILE *g;
    int rc;

    memset(&z, 0, sizeof(z));
    rc = write_surfaces(o, mdl, t, fps, &nfp, &z, &npoints);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    g = tmp_open(t, "plot.gp");
    if (g == NULL) {
        return CLI_EXIT_DATA;
    }
    put_terminal(g, o);
    fprintf(g, "set xlabel 'x'\nset ylabel 'y'\n"
               "set view 60,35\nset xyplane relative 0\nset grid\n"
               "set hidden3d front\n"
               "set border 4095 lc rgb '#808080'\n");
    fputs("surf = ", g);
    put_quoted(g, t->path[0]);
    fputs("\nnets = ", g);
    put_quoted(g, t->path[1]);
    fputs("\npts = ", g);
    put_quoted(g, t->path[2]);
    fputc('\n', g);
    snprintf(title, sizeof(title),
             "%s: %u footprint surface%s%s, %ux%u "
             "samples",
             base_name(o), nfp, nfp == 1u ? "" : "s", o->nets ? " with control nets" : "", o->rows, o->cols);
    if (o->membership < 0) {
        /* Three panels, T, I and F, each scaled to itself: drawn in one
         * box I hid behind F. */
        fputs("set multiplot layout 1,3 title ", g);
        put_quoted(g, title);
        fputc('\n', g);
        for (k = 0; k < 3u; k++) {
            fprintf(g, "set title '%s %s'\n", memb_long[k], memb_short[k]);
            put_panel(g, o, mdl, fps, nfp, k, &z, npoints,
                      "below center horizontal maxrows 3 samplen 2 width -6 spacing 1.1 box");
        }
        fputs("unset multiplot\n", g);
    } else {
        k = (unsigned)o->membership;
        snprintf(title, sizeof(title),
                 "%s: %s %s of %u footprint surface%s%s,"
                 " %ux%u samples",
                 base_name(o), memb_long[k], memb_short[k], nfp, nfp == 1u ? "" : "s",
                 o->nets ? " with control nets" : "", o->rows, o->cols);
        fputs("set title ", g);
        put_quoted(g, title);
        fputc('\n', g);
        put_panel(g, o, mdl, fps, nfp, k, &z, npoints, "outside right top vertical spacing 1.1 box");
    }
    return tmp_close(g);
}

/* A rectangle in (x, y), Q24. */
typedef struct xybox {
    it2n_val x0, x1, y0, y1;
} xybox;

/* The bands at one (x, y): every footprint located through it. ok[b] when
 * all three footprints of band b (upper LL, D, RR; lower LR, D, RL) pass
 * there; lo/hi their extremes of channel ch. */
static int band_at(const cli_surface *mdl, it2n_val x, it2n_val y, unsigned ch, bool ok[2], it2n_val lo[2],
                   it2n_val hi[2])
{
    static const unsigned set[2][3] = {{IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR}, {IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL}};
    it2n_locate_result res;
    unsigned b, s;
    int rc = cli_surf_locate(mdl, x, y, &res, NULL);
    if (rc != IT2N_OK) {
        fprintf(stderr, "it2n: locate failed: %s\n", it2n_strerror(rc));
        return CLI_EXIT_DATA;
    }
    for (b = 0; b < 2u; b++) {
        ok[b] = true;
        lo[b] = hi[b] = res.fp[set[b][0]].v[ch];
        for (s = 0; s < 3u; s++) {
            const it2n_locate_fp *lf = &res.fp[set[b][s]];
            ok[b] = ok[b] && lf->status == IT2N_LOC_INSIDE;
            lo[b] = lf->v[ch] < lo[b] ? lf->v[ch] : lo[b];
            hi[b] = lf->v[ch] > hi[b] ? lf->v[ch] : hi[b];
        }
    }
    return CLI_EXIT_OK;
}

static it2n_val grid_at(it2n_val a, it2n_val b, unsigned i, unsigned n)
{
    return a + (b - a) * (it2n_val)i / (it2n_val)(n - 1u);
}

/* The box of the nodes of a rows x cols grid over *in where a band is known,
 * widened by one cell (the region's edge lies between nodes) and kept in
 * *in. Returns false if no node has a band. */
static int band_region(const cli_surface *mdl, unsigned ch, const xybox *in, unsigned rows, unsigned cols, xybox *out,
                       bool *any)
{
    unsigned r, c;
    it2n_val dx = (in->x1 - in->x0) / (it2n_val)(cols - 1u);
    it2n_val dy = (in->y1 - in->y0) / (it2n_val)(rows - 1u);
    *any = false;
    for (r = 0; r < rows; r++) {
        for (c = 0; c < cols; c++) {
            it2n_val x = grid_at(in->x0, in->x1, c, cols);
            it2n_val y = grid_at(in->y0, in->y1, r, rows);
            it2n_val lo[2], hi[2];
            bool ok[2];
            int rc = band_at(mdl, x, y, ch, ok, lo, hi);
            if (rc != CLI_EXIT_OK) {
                return rc;
            }
            if (!ok[0] && !ok[1]) {
                continue;
            }
            if (!*any) {
                out->x0 = out->x1 = x;
                out->y0 = out->y1 = y;
            }
            *any = true;
            out->x0 = x < out->x0 ? x : out->x0;
            out->x1 = x > out->x1 ? x : out->x1;
            out->y0 = y < out->y0 ? y : out->y0;
            out->y1 = y > out->y1 ? y : out->y1;
        }
    }
    if (*any) {
        out->x0 = out->x0 - dx > in->x0 ? out->x0 - dx : in->x0;
        out->x1 = out->x1 + dx < in->x1 ? out->x1 + dx : in->x1;
        out->y0 = out->y0 - dy > in->y0 ? out->y0 - dy : in->y0;
        out->y1 = out->y1 + dy < in->y1 ? out->y1 + dy : in->y1;
    }
    return CLI_EXIT_OK;
}

/* Extent in (x, y) of every footprint surface, sampled on a 21x21 grid. */
static int xy_extent(const cli_surface *mdl, xybox *all)
{
    unsigned r, c, fp;
    cli_mesh mesh;
    int rc = cli_mesh_sample(&mesh, mdl, 21u, 21u);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    all->x0 = all->x1 = cli_mesh_at(&mesh, 0, 0, 0, IT2N_CH_X);
    all->y0 = all->y1 = cli_mesh_at(&mesh, 0, 0, 0, IT2N_CH_Y);
    for (r = 0; r < mesh.rows; r++) {
        for (c = 0; c < mesh.cols; c++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val x = cli_mesh_at(&mesh, r, c, fp, IT2N_CH_X);
                it2n_val y = cli_mesh_at(&mesh, r, c, fp, IT2N_CH_Y);
                all->x0 = x < all->x0 ? x : all->x0;
                all->x1 = x > all->x1 ? x : all->x1;
                all->y0 = y < all->y0 ? y : all->y0;
                all->y1 = y > all->y1 ? y : all->y1;
            }
        }
    }
    cli_mesh_free(&mesh);
    return CLI_EXIT_OK;
}

/* One line of band.dat: x y, the two band widths, their bounds ('?' where
 * a band's footprints do not all pass through (x, y)). */
static void put_band_line(FILE *d, it2n_val x, it2n_val y, const bool ok[2], const it2n_val lo[2], const it2n_val hi[2],
                          unsigned decimals)
{
    unsigned b;
    put_val(d, x, decimals);
    fputc(' ', d);
    put_val(d, y, decimals);
    for (b = 0; b < 2u; b++) {
        fputc(' ', d);
        if (ok[b]) {
            put_val(d, hi[b] - lo[b], decimals);
        } else {
            fputc('?', d);
        }
    }
    for (b = 0; b < 2u; b++) {
        fputc(' ', d);
        if (ok[b]) {
            put_val(d, lo[b], decimals);
            fputc(' ', d);
            put_val(d, hi[b], decimals);
        } else {
            fputs("? ?", d);
        }
    }
    fputc('\n', d);
}

/* band.dat over box: *wmax the widest band, *known the nodes with one. */
static int write_band_data(const cli_opts *o, const cli_surface *mdl, const xybox *box, tmpfiles *t, it2n_val *wmax,
                           unsigned *known)
{
    const unsigned k = (unsigned)o->membership, ch = IT2N_CH_T + k;
    unsigned r, c, b;
    FILE *d = tmp_open(t, "band.dat");
    if (d == NULL) {
        return CLI_EXIT_DATA;
    }
    fprintf(d,
            "# x y upper_width lower_width upper_min upper_max lower_min "
            "lower_max of %s ('?': not every footprint passes here)\n",
            memb_short[k]);
    for (r = 0; r < o->rows; r++) {
        it2n_val y = grid_at(box->y0, box->y1, r, o->rows);
        for (c = 0; c < o->cols; c++) {
            it2n_val x = grid_at(box->x0, box->x1, c, o->cols);
            it2n_val lo[2], hi[2];
            bool ok[2];
            int rc = band_at(mdl, x, y, ch, ok, lo, hi);
            if (rc != CLI_EXIT_OK) {
                fclose(d);
                return rc;
            }
            for (b = 0; b < 2u; b++) {
                if (ok[b] && hi[b] - lo[b] > *wmax) {
                    *wmax = hi[b] - lo[b];
                }
            }
            *known += ok[0] || ok[1];
            put_band_line(d, x, y, ok, lo, hi, o->decimals);
        }
        fputc('\n', d);
    }
    return tmp_close(d);
}

/* plot.gp: the two heat maps of band.dat side by side. */
static int write_band_script(const cli_opts *o, const xybox *box, it2n_val wmax, tmpfiles *t)
{
    const unsigned k = (unsigned)o->membership;
    char title[512];
    FILE *g = tmp_open(t, "plot.gp");
    if (g == NULL) {
        return CLI_EXIT_DATA;
    }
    put_terminal(g, o);
    snprintf(title, sizeof(title),
             "%s: interval of the %s membership %s over (x, y), "
             "%ux%u nodes",
             base_name(o), memb_long[k], memb_short[k], o->rows, o->cols);
    fputs("set multiplot layout 1,2 margins 0.06,0.87,0.1,0.86 "
          "spacing 0.16 title ",
          g);
    put_quoted(g, title);
    fprintf(g,
            "\nset datafile missing '?'\nset view map\nset size ratio -1\n"
            "set xlabel 'x'\nset ylabel 'y'\nset key off\n"
            "set palette defined (0 '#ffffff', 1 '%s', 2 '#000000')\n"
            "set cbrange [0:",
            colour[k][CLS_TYPE1]);
    put_val(g, wmax > 0 ? wmax : IT2N_VAL_ONE, o->decimals);
    fprintf(g,
            "]\nset cblabel 'band width of %s' rotate\n"
            "set xrange [",
            memb_short[k]);
    put_val(g, box->x0, o->decimals);
    fputc(':', g);
    put_val(g, box->x1, o->decimals);
    fputs("]\nset yrange [", g);
    put_val(g, box->y0, o->decimals);
    fputc(':', g);
    put_val(g, box->y1, o->decimals);
    fputs("]\nband = ", g);
    put_quoted(g, t->path[0]);
    fprintf(g,
            "\nset title 'upper band: max - min of %s over LL, D, RR'\n"
            "splot band using 1:2:3 with pm3d\n"
            "set title 'lower band: max - min of %s over LR, D, RL'\n"
            "splot band using 1:2:4 with pm3d\nunset multiplot\n",
            memb_short[k], memb_short[k]);
    return tmp_close(g);
}

/* Interval band over (x, y): every footprint located through each node of
 * a grid over the region the bands cover (found on a coarse grid first, so
 * the map is not a small patch in a wide white frame). */
static int script_interval(const cli_opts *o, const cli_surface *mdl, tmpfiles *t)
{
    const unsigned ch = IT2N_CH_T + (unsigned)o->membership;
    it2n_val wmax = 0;
    xybox all, box;
    unsigned known = 0;
    bool any;
    int rc;

    if (cli_surf_flags(mdl) & IT2N_F_TYPE1) {
        fprintf(stderr,
                "%s: --interval: a type-1 model (footprint D only) has no "
                "interval\n",
                cli_display_name(o->path));
        return CLI_EXIT_DATA;
    }
    rc = xy_extent(mdl, &all);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    rc = band_region(mdl, ch, &all, 41u, 41u, &box, &any);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    if (!any) {
        box = all; /* the fine grid may still find some: it says if not */
    }
    rc = write_band_data(o, mdl, &box, t, &wmax, &known);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    if (known == 0u) {
        fprintf(stderr,
                "it2n: --interval: no (x, y) node on the %ux%u grid lies on "
                "all of LL, D, RR or LR, D, RL\n",
                o->rows, o->cols);
        return CLI_EXIT_DATA;
    }
    return write_band_script(o, &box, wmax, t);
}

/* Run gnuplot on the script; its own messages go to stderr. */
static int run_gnuplot(const cli_opts *o, const char *script)
{
    const char *prog = getenv("IT2N_GNUPLOT");
    char *argv[3];
    posix_spawn_file_actions_t fa;
    pid_t pid;
    int rc, status;

    if (prog == NULL || prog[0] == '\0') {
        prog = "gnuplot";
    }
    argv[0] = (char *)prog;
    argv[1] = (char *)script;
    argv[2] = NULL;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", 0, 0);
    rc = posix_spawnp(&pid, prog, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        fprintf(stderr,
                "it2n: cannot run %s: %s (plot needs gnuplot on PATH, "
                "Debian package gnuplot-nox, or IT2N_GNUPLOT=/path/to/gnuplot)\n",
                prog, strerror(rc));
        return CLI_EXIT_DATA;
    }
    while (waitpid(pid, &status, 0) < 0) {
        if (errno != EINTR) {
            fprintf(stderr, "it2n: waiting for %s: %s\n", prog, strerror(errno));
            return CLI_EXIT_DATA;
        }
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "it2n: %s failed (%s %d) drawing %s\n", prog, WIFEXITED(status) ? "exit status" : "signal",
                WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status), o->output);
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

int cli_plot(const cli_opts *o, const cli_surface *mdl)
{
    const char *tmp = getenv("TMPDIR");
    tmpfiles t;
    FILE *probe;
    bool existed = access(o->output, F_OK) == 0;
    int rc;

    memset(&t, 0, sizeof(t));
    /* Fail early, as gnuplot would only warn, if FILE cannot be written;
     * a file this run created is removed again on failure. */
    probe = fopen(o->output, "a");
    if (probe == NULL) {
        fprintf(stderr, "%s: cannot create: %s\n", o->output, strerror(errno));
        return CLI_EXIT_DATA;
    }
    fclose(probe);
    snprintf(t.dir, sizeof(t.dir), "%s/it2n-plot.XXXXXX", tmp && tmp[0] ? tmp : "/tmp");
    if (mkdtemp(t.dir) == NULL) {
        fprintf(stderr, "it2n: cannot create a temporary directory %s: %s\n", t.dir, strerror(errno));
        return CLI_EXIT_DATA;
    }
    rc = o->interval ? script_interval(o, mdl, &t) : script_surfaces(o, mdl, &t);
    if (rc == CLI_EXIT_OK) {
        rc = run_gnuplot(o, t.path[t.n - 1u]);
    }
    tmp_remove(&t);
    if (rc != CLI_EXIT_OK && !existed) {
        unlink(o->output);
    }
    return rc;
}
