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

static const char *const memb_long[3] = {"truth", "indeterminacy",
                                         "falsity"};
static const char *const memb_short[3] = {"T", "I", "F"};

/* Footprint classes: how a surface is drawn. */
enum { CLS_UPPER = 0, CLS_LOWER, CLS_INNER, CLS_TYPE1, CLS_COUNT };
static const char *const cls_name[CLS_COUNT] = {
    "upper (LL, RR)", "lower (LR, RL)", "inner (L, R)", "type-1 D"};
static const char *const cls_dash[CLS_COUNT] = {"1", "2", "3", "1"};
static const char *const cls_width[CLS_COUNT] = {"1.2", "1.2", "1.2", "2.5"};
/* Paper colours: truth green, indeterminacy blue, falsity red; one shade
 * per class (upper darkest, lower lightest). */
static const char *const colour[3][CLS_COUNT] = {
    {"#00441b", "#74c476", "#238b45", "#1a9641"},
    {"#08306b", "#6baed6", "#2171b5", "#2166ac"},
    {"#67000d", "#fb6a4a", "#cb181d", "#d7191c"}};

static unsigned fp_class(unsigned fp)
{
    switch (fp) {
    case IT2N_FP_LL:
    case IT2N_FP_RR:
        return CLS_UPPER;
    case IT2N_FP_LR:
    case IT2N_FP_RL:
        return CLS_LOWER;
    case IT2N_FP_L:
    case IT2N_FP_R:
        return CLS_INNER;
    default:
        return CLS_TYPE1;
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
    char path[4][600];
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
        fprintf(stderr, "it2n: cannot create %s: %s\n", t->path[t->n],
                strerror(errno));
    }
    return f;
}

static int tmp_close(FILE *f)
{
    bool bad = fflush(f) != 0 || ferror(f);
    if (fclose(f) != 0 || bad) {
        fprintf(stderr, "it2n: cannot write temporary file: %s\n",
                strerror(errno));
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

static void put_terminal(FILE *g, const cli_opts *o)
{
    const char *dot = strrchr(o->output, '.');
    bool svg = dot != NULL && strcasecmp(dot, ".svg") == 0;
    fprintf(g,
            "set terminal %s size %u,%u noenhanced font 'sans,%u' "
            "background '#ffffff'\n",
            svg ? "svg" : "pngcairo", o->width, o->height,
            o->width >= 1400u ? 12u : 10u);
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

/* Surfaces and control nets: data blocks, one per selected footprint. */
static int write_surfaces(const cli_opts *o, const it2n_model *mdl,
                          tmpfiles *t, unsigned fps[], unsigned *nfp)
{
    cli_mesh mesh;
    FILE *s, *n;
    unsigned a, fp, r, c, ch;
    int rc = cli_mesh_sample(&mesh, mdl, o->rows, o->cols);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    *nfp = 0;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (cli_fp_selected(o, mdl, fp)) {
            fps[(*nfp)++] = fp;
        }
    }
    s = tmp_open(t, "surfaces.dat");
    n = s ? tmp_open(t, "nets.dat") : NULL;
    if (s == NULL || n == NULL) {
        if (s) {
            fclose(s);
        }
        cli_mesh_free(&mesh);
        return CLI_EXIT_DATA;
    }
    for (a = 0; a < *nfp; a++) {
        fp = fps[a];
        fprintf(s, "# footprint %s: x y T I F, %u rows of %u samples\n",
                it2n_fp_name(fp), mesh.rows, mesh.cols);
        for (r = 0; r < mesh.rows; r++) {
            for (c = 0; c < mesh.cols; c++) {
                for (ch = IT2N_CH_X; ch < IT2N_CH_COUNT; ch++) {
                    if (ch == IT2N_CH_Z) {
                        continue;
                    }
                    if (ch != IT2N_CH_X) {
                        fputc(' ', s);
                    }
                    put_val(s, cli_mesh_at(&mesh, r, c, fp, ch), o->decimals);
                }
                fputc('\n', s);
            }
            fputc('\n', s);
        }
        fputs("\n", s);
        fprintf(n, "# control net %s: x y T I F\n", it2n_fp_name(fp));
        for (r = 0; r <= mdl->n; r++) {
            for (c = 0; c <= mdl->m; c++) {
                for (ch = IT2N_CH_X; ch < IT2N_CH_COUNT; ch++) {
                    if (ch == IT2N_CH_Z) {
                        continue;
                    }
                    if (ch != IT2N_CH_X) {
                        fputc(' ', n);
                    }
                    put_val(n, it2n_model_ctrl(mdl, r, c, fp, ch),
                            o->decimals);
                }
                fputc('\n', n);
            }
            fputc('\n', n);
        }
        fputs("\n", n);
    }
    cli_mesh_free(&mesh);
    rc = tmp_close(s);
    if (tmp_close(n) != CLI_EXIT_OK) {
        rc = CLI_EXIT_DATA;
    }
    return rc;
}

static int script_surfaces(const cli_opts *o, const it2n_model *mdl,
                           tmpfiles *t)
{
    unsigned fps[IT2N_FP_COUNT], nfp, a, k, k0, k1;
    bool first = true;
    FILE *g;
    int rc = write_surfaces(o, mdl, t, fps, &nfp);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    g = tmp_open(t, "plot.gp");
    if (g == NULL) {
        return CLI_EXIT_DATA;
    }
    k0 = o->membership < 0 ? 0u : (unsigned)o->membership;
    k1 = o->membership < 0 ? 3u : k0 + 1u;
    put_terminal(g, o);
    fputs("set title ", g);
    {
        char title[512];
        if (o->membership < 0) {
            snprintf(title, sizeof(title),
                     "%s: truth T, indeterminacy I, falsity F of %u "
                     "footprint surface%s with control nets (%ux%u samples)",
                     base_name(o), nfp, nfp == 1u ? "" : "s", o->rows,
                     o->cols);
        } else {
            snprintf(title, sizeof(title),
                     "%s: %s membership %s of %u footprint surface%s with "
                     "control nets (%ux%u samples)",
                     base_name(o), memb_long[k0], memb_short[k0], nfp,
                     nfp == 1u ? "" : "s", o->rows, o->cols);
        }
        put_quoted(g, title);
    }
    fprintf(g,
            "\nset xlabel 'x'\nset ylabel 'y'\n"
            "set zlabel '%s' rotate parallel\n"
            "set view 60,35\nset xyplane relative 0\nset grid\n"
            "set key outside right top vertical spacing 1.1 box\n"
            "set border 4095 lc rgb '#808080'\n",
            o->membership < 0 ? "membership" : memb_long[k0]);
    fputs("surf = ", g);
    put_quoted(g, t->path[0]);
    fputs("\nnets = ", g);
    put_quoted(g, t->path[1]);
    fputs("\nsplot \\\n", g);
    for (k = k0; k < k1; k++) {
        bool cls_seen[CLS_COUNT] = {false, false, false, false};
        for (a = 0; a < nfp; a++) {
            unsigned cl = fp_class(fps[a]);
            fprintf(g, "%s  surf index %u using 1:2:%u with lines lc rgb '%s' "
                       "dt %s lw %s ",
                    first ? "" : ", \\\n", a, 3u + k,
                    colour[k][cl], cls_dash[cl], cls_width[cl]);
            first = false;
            if (cls_seen[cl]) {
                fputs("notitle", g);
            } else {
                fprintf(g, "title '%s %s'", memb_short[k], cls_name[cl]);
                cls_seen[cl] = true;
            }
            /* Nets half transparent (#AARRGGBB) so the surfaces stay
             * readable through them. */
            fprintf(g, ", \\\n  nets index %u using 1:2:%u with linespoints "
                       "lc rgb '#80%s' dt 1 lw 0.6 pt 7 ps 0.5 ",
                    a, 3u + k, colour[k][cl] + 1);
            if (a == 0u) {
                fprintf(g, "title '%s control nets'", memb_short[k]);
            } else {
                fputs("notitle", g);
            }
        }
    }
    fputs("\n", g);
    return tmp_close(g);
}

/* Interval band over (x, y): every footprint located through each node. */
static int script_interval(const cli_opts *o, const it2n_model *mdl,
                           tmpfiles *t)
{
    static const unsigned upper[3] = {IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR};
    static const unsigned lower[3] = {IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL};
    const unsigned k = (unsigned)o->membership, ch = IT2N_CH_T + k;
    it2n_val xmin = 0, xmax = 0, ymin = 0, ymax = 0, wmax = 0;
    it2n_locate_result res;
    unsigned r, c, fp, known = 0, nodes = 0;
    cli_mesh mesh;
    FILE *d, *g;
    int rc;

    if (mdl->flags & IT2N_F_TYPE1) {
        fprintf(stderr,
                "%s: --interval: a type-1 model (footprint D only) has no "
                "interval\n",
                strcmp(o->path, "-") == 0 ? "<stdin>" : o->path);
        return CLI_EXIT_DATA;
    }
    /* Extent in (x, y): every footprint surface sampled on the grid. */
    rc = cli_mesh_sample(&mesh, mdl, o->rows, o->cols);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    xmin = xmax = cli_mesh_at(&mesh, 0, 0, 0, IT2N_CH_X);
    ymin = ymax = cli_mesh_at(&mesh, 0, 0, 0, IT2N_CH_Y);
    for (r = 0; r < mesh.rows; r++) {
        for (c = 0; c < mesh.cols; c++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val x = cli_mesh_at(&mesh, r, c, fp, IT2N_CH_X);
                it2n_val y = cli_mesh_at(&mesh, r, c, fp, IT2N_CH_Y);
                xmin = x < xmin ? x : xmin;
                xmax = x > xmax ? x : xmax;
                ymin = y < ymin ? y : ymin;
                ymax = y > ymax ? y : ymax;
            }
        }
    }
    cli_mesh_free(&mesh);

    d = tmp_open(t, "band.dat");
    if (d == NULL) {
        return CLI_EXIT_DATA;
    }
    fprintf(d, "# x y upper_width lower_width upper_min upper_max lower_min "
               "lower_max of %s ('?': not every footprint passes here)\n",
            memb_short[k]);
    for (r = 0; r < o->rows; r++) {
        it2n_val y = ymin + (ymax - ymin) * (it2n_val)r / (it2n_val)(o->rows - 1u);
        for (c = 0; c < o->cols; c++) {
            it2n_val x =
                xmin + (xmax - xmin) * (it2n_val)c / (it2n_val)(o->cols - 1u);
            it2n_val lo[2], hi[2];
            bool ok[2] = {true, true};
            unsigned b, s;
            rc = it2n_locate(mdl, x, y, &res, NULL);
            if (rc != IT2N_OK) {
                fclose(d);
                fprintf(stderr, "it2n: locate failed: %s\n",
                        it2n_strerror(rc));
                return CLI_EXIT_DATA;
            }
            for (b = 0; b < 2u; b++) {
                const unsigned *set = b == 0u ? upper : lower;
                lo[b] = hi[b] = res.fp[set[0]].v[ch];
                for (s = 0; s < 3u; s++) {
                    const it2n_locate_fp *lf = &res.fp[set[s]];
                    it2n_val v = lf->v[ch];
                    if (lf->status != IT2N_LOC_INSIDE) {
                        ok[b] = false;
                    }
                    lo[b] = v < lo[b] ? v : lo[b];
                    hi[b] = v > hi[b] ? v : hi[b];
                }
                if (ok[b] && hi[b] - lo[b] > wmax) {
                    wmax = hi[b] - lo[b];
                }
            }
            nodes++;
            known += ok[0] || ok[1];
            put_val(d, x, o->decimals);
            fputc(' ', d);
            put_val(d, y, o->decimals);
            for (b = 0; b < 2u; b++) {
                fputc(' ', d);
                if (ok[b]) {
                    put_val(d, hi[b] - lo[b], o->decimals);
                } else {
                    fputc('?', d);
                }
            }
            for (b = 0; b < 2u; b++) {
                fputc(' ', d);
                if (ok[b]) {
                    put_val(d, lo[b], o->decimals);
                    fputc(' ', d);
                    put_val(d, hi[b], o->decimals);
                } else {
                    fputs("? ?", d);
                }
            }
            fputc('\n', d);
        }
        fputc('\n', d);
    }
    rc = tmp_close(d);
    if (rc != CLI_EXIT_OK) {
        return rc;
    }
    (void)nodes;
    if (known == 0u) {
        fprintf(stderr,
                "it2n: --interval: no (x, y) node on the %ux%u grid lies on "
                "all of LL, D, RR or LR, D, RL\n",
                o->rows, o->cols);
        return CLI_EXIT_DATA;
    }

    g = tmp_open(t, "plot.gp");
    if (g == NULL) {
        return CLI_EXIT_DATA;
    }
    put_terminal(g, o);
    {
        char title[512];
        snprintf(title, sizeof(title),
                 "%s: interval of the %s membership %s over (x, y), "
                 "%ux%u nodes",
                 base_name(o), memb_long[k], memb_short[k], o->rows, o->cols);
        fputs("set multiplot layout 1,2 title ", g);
        put_quoted(g, title);
    }
    fprintf(g,
            "\nset datafile missing '?'\nset view map\nset size ratio -1\n"
            "set xlabel 'x'\nset ylabel 'y'\nset key off\n"
            "set palette defined (0 '#ffffff', 1 '%s', 2 '#000000')\n"
            "set cbrange [0:",
            colour[k][CLS_TYPE1]);
    put_val(g, wmax > 0 ? wmax : IT2N_VAL_ONE, o->decimals);
    fprintf(g, "]\nset cblabel 'band width of %s' rotate\n"
               "set xrange [",
            memb_short[k]);
    put_val(g, xmin, o->decimals);
    fputc(':', g);
    put_val(g, xmax, o->decimals);
    fputs("]\nset yrange [", g);
    put_val(g, ymin, o->decimals);
    fputc(':', g);
    put_val(g, ymax, o->decimals);
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
            fprintf(stderr, "it2n: waiting for %s: %s\n", prog,
                    strerror(errno));
            return CLI_EXIT_DATA;
        }
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        fprintf(stderr, "it2n: %s failed (%s %d) drawing %s\n", prog,
                WIFEXITED(status) ? "exit status" : "signal",
                WIFEXITED(status) ? WEXITSTATUS(status) : WTERMSIG(status),
                o->output);
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

int cli_plot(const cli_opts *o, const it2n_model *mdl,
             const it2n_dataset *ds)
{
    const char *tmp = getenv("TMPDIR");
    tmpfiles t;
    FILE *probe;
    bool existed = access(o->output, F_OK) == 0;
    int rc;

    (void)ds;
    memset(&t, 0, sizeof(t));
    /* Fail early, as gnuplot would only warn, if FILE cannot be written;
     * a file this run created is removed again on failure. */
    probe = fopen(o->output, "a");
    if (probe == NULL) {
        fprintf(stderr, "%s: cannot create: %s\n", o->output,
                strerror(errno));
        return CLI_EXIT_DATA;
    }
    fclose(probe);
    snprintf(t.dir, sizeof(t.dir), "%s/it2n-plot.XXXXXX",
             tmp && tmp[0] ? tmp : "/tmp");
    if (mkdtemp(t.dir) == NULL) {
        fprintf(stderr, "it2n: cannot create a temporary directory %s: %s\n",
                t.dir, strerror(errno));
        return CLI_EXIT_DATA;
    }
    rc = o->interval ? script_interval(o, mdl, &t)
                     : script_surfaces(o, mdl, &t);
    if (rc == CLI_EXIT_OK) {
        rc = run_gnuplot(o, t.path[t.n - 1u]);
    }
    tmp_remove(&t);
    if (rc != CLI_EXIT_OK && !existed) {
        unlink(o->output);
    }
    return rc;
}
