/*
 * it2nctl's commands but plot (ctl_live.c): each asks the daemon through
 * the session's transport and prints it2n's rows (cli/common/out.c).
 */
#include "cli.h"
#include "csv.h"
#include "ctl.h"
#include "ctl_cmds.h"
#include "out.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

cli_out ctl_out;

static bool has_fp(unsigned fp)
{
    return cli_out_has_fp(&ctl_out, fp);
}

const char *ctl_state_name(int state)
{
    switch (state) {
    case CTL_ST_EMPTY: return "empty";
    case CTL_ST_INCOMPLETE: return "incomplete";
    case CTL_ST_SOLVED: return "solved";
    case CTL_ST_FAILED: return "failed";
    default: return "?";
    }
}

int ctl_wrong_kind(const char *where, bool held_bspline, const cli_data *src, const char *nothing)
{
    const char *want = src->bds != NULL ? "bspline" : "bezier";
    fprintf(stderr,
            "it2nctl: %s holds a %s model and the data are for the %s kind: push --kind %s to a [model:ID] with "
            "kind = %s (nothing was %s)\n",
            where, held_bspline ? "bspline" : "bezier", want, want, want, nothing);
    return CTL_EXIT_DATA;
}

void ctl_summarise(bool type1, it2n_point *pt)
{
    static const unsigned char upper[3] = {IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR};
    static const unsigned char lower[3] = {IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL};
    unsigned k, f, fp;
    pt->out_of_range = 0u;
    for (k = 0; k < 3u; k++) {
        unsigned ch = IT2N_CH_T + k;
        it2n_val d = pt->v[IT2N_FP_D][ch];
        pt->sum.upper_min[k] = pt->sum.upper_max[k] = d;
        pt->sum.lower_min[k] = pt->sum.lower_max[k] = d;
        for (f = 0; f < 3u && !type1; f++) {
            it2n_val a = pt->v[upper[f]][ch], b = pt->v[lower[f]][ch];
            if (a < pt->sum.upper_min[k])
                pt->sum.upper_min[k] = a;
            if (a > pt->sum.upper_max[k])
                pt->sum.upper_max[k] = a;
            if (b < pt->sum.lower_min[k])
                pt->sum.lower_min[k] = b;
            if (b > pt->sum.lower_max[k])
                pt->sum.lower_max[k] = b;
        }
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            it2n_val v = pt->v[fp][ch];
            if ((type1 ? fp == IT2N_FP_D : true) && (v < 0 || v > IT2N_VAL_ONE)) {
                pt->out_of_range |= (uint32_t)1u << (fp * 3u + k);
            }
        }
    }
}

/* Status, and the model must be solved for queries. */
int ctl_solved_status(ctl_session *s, const ctl_args *a, ctl_status *st)
{
    int rc = s->ops->status(s->c, st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    cli_out_init(&ctl_out, st->flags, a->o.decimals, a->o.fpmask, a->o.summary);
    if (st->state != CTL_ST_SOLVED) {
        fprintf(stderr,
                "it2nctl: %s: the model is not solved (state %s, %u of %u "
                "points%s)\n",
                s->where, ctl_state_name(st->state), st->present, st->required,
                st->state == CTL_ST_FAILED ? "; see last_error in status" : "");
        return CTL_EXIT_DATA;
    }
    return CTL_EXIT_OK;
}

static void put_status_header(void)
{
    puts("model,state,n,m,type,coordinates,parameters,points_present,"
         "points_required,generation,last_error,kind");
}

static void put_status_row(const ctl_status *st)
{
    printf("%u,%s,%u,%u,%s,%s,%s,%u,%u,%lu,%d,%s\n", st->model, ctl_state_name(st->state), st->n, st->m,
           (st->flags & IT2N_F_TYPE1) ? "type-1" : "type-2", (st->flags & IT2N_F_Z) ? "xyz" : "xy",
           (st->flags & IT2N_F_CHORD) ? "chord-length" : "uniform", st->present, st->required,
           (unsigned long)st->generation, st->last_error, st->kind ? "bspline" : "bezier");
}

int ctl_cmd_status(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    int rc = s->ops->status(s->c, &st);
    (void)a;
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    put_status_header();
    put_status_row(&st);
    return cli_finish_output("it2nctl");
}

/* Wait for the next generation after gen worth a row or a drawing: a solved
 * or failed model at once; an empty or incomplete one (a push configures,
 * clears and uploads before it commits) only once it has stood unchanged
 * for WATCH_SETTLE_MS — a cleared or abandoned model is shown, a push in
 * progress is not — or at once when every generation is asked for. */
#define WATCH_SETTLE_MS 1000
int ctl_next_generation(ctl_session *s, bool every, uint32_t gen, ctl_status *st)
{
    int rc;
    for (;;) {
        rc = s->ops->wait(s->c, gen, 1000, st);
        if (rc != CTL_EXIT_OK || st->generation == gen) {
            if (rc != CTL_EXIT_OK) {
                return rc;
            }
            continue;
        }
        if (every || st->state == CTL_ST_SOLVED || st->state == CTL_ST_FAILED) {
            return CTL_EXIT_OK;
        }
        /* A transport's wait may return early (an event that kept the
         * generation): the settling time is measured here. */
        gen = st->generation;
        {
            struct timespec t0, t;
            long left = WATCH_SETTLE_MS;
            clock_gettime(CLOCK_MONOTONIC, &t0);
            while (left > 0 && st->generation == gen) {
                rc = s->ops->wait(s->c, gen, (int)left, st);
                if (rc != CTL_EXIT_OK) {
                    return rc;
                }
                clock_gettime(CLOCK_MONOTONIC, &t);
                left = WATCH_SETTLE_MS - ((t.tv_sec - t0.tv_sec) * 1000L + (t.tv_nsec - t0.tv_nsec) / 1000000L);
            }
        }
        if (st->generation == gen) {
            return CTL_EXIT_OK; /* settled */
        }
        gen = st->generation - 1u; /* moved on: judge the new one */
    }
}

int ctl_cmd_watch(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    unsigned rows = 0;
    uint32_t gen;
    int rc = s->ops->status(s->c, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    put_status_header();
    for (;;) {
        put_status_row(&st);
        fflush(stdout);
        if (ferror(stdout)) {
            return cli_finish_output("it2nctl");
        }
        if (a->count != 0u && ++rows >= a->count) {
            return cli_finish_output("it2nctl");
        }
        gen = st.generation;
        rc = ctl_next_generation(s, a->incomplete, gen, &st);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
    }
}

static cli_csv_reader g_csv;
static it2n_dataset g_ds;
static it2n_model g_mdl;

/* Read, check and solve DATA.csv exactly as it2n does (the same code). */
static const it2n_bspline_data *g_bds; /* push --kind bspline */
static const cli_csv_reader *g_bcsv;

int ctl_load(const cli_opts *o)
{
    if (o->kind == CLI_KIND_BSPLINE) {
        const it2n_bspline_model *bm;
        if (o->flags & IT2N_F_CHORD) {
            fprintf(stderr, "it2nctl push: --chord: the B-spline kind has "
                            "uniform parameters only\n");
            return CTL_EXIT_USAGE;
        }
        return cli_load_bspline(o, &g_bds, &bm, &g_bcsv) == CLI_EXIT_OK ? CTL_EXIT_OK : CTL_EXIT_DATA;
    }
    return cli_load(o, &g_csv, &g_ds, &g_mdl) == CLI_EXIT_OK ? CTL_EXIT_OK : CTL_EXIT_DATA;
}

static bool g_bar_open; /* a progress line without its newline */

static void progress_bar(void *ctx, unsigned done, unsigned total)
{
    const unsigned width = 40u;
    unsigned k, fill = total ? done * width / total : width;
    (void)ctx;
    g_bar_open = done != total;
    fputs("\rpush [", stderr);
    for (k = 0; k < width; k++) {
        fputc(k < fill ? '#' : '.', stderr);
    }
    fprintf(stderr, "] %u/%u points", done, total);
    if (done == total) {
        fputc('\n', stderr);
    }
    fflush(stderr);
}

int ctl_cmd_push(ctl_session *s, const ctl_args *a)
{
    const char *name = cli_display_name(a->o.path);
    const cli_data src = g_bds != NULL ? cli_data_bspline(g_bds) : cli_data_bezier(&g_ds);
    it2n_errinfo rej;
    ctl_status st;
    char msg[600];
    int rc;
    rc = s->ops->push(s->c, &src, isatty(2) ? progress_bar : NULL, NULL, &rej);
    if (g_bar_open) { /* failed midway: the message on its own line */
        fputc('\n', stderr);
        g_bar_open = false;
    }
    if (rc == CTL_REJECTED) {
        cli_csv_error e;
        unsigned long line = 0;
        if (rej.i >= 0 && rej.j >= 0 && rej.fp >= 0 && rej.i < IT2N_DIM && rej.j < IT2N_DIM && rej.fp < IT2N_FP_COUNT) {
            line = g_csv.lines[rej.i][rej.j][rej.fp];
        }
        if (g_bds != NULL && rej.i >= 0 && rej.j >= 0 && rej.fp >= 0 && rej.i <= IT2N_BSPLINE_MAX_N &&
            rej.j <= IT2N_BSPLINE_MAX_N && rej.fp < IT2N_FP_COUNT) {
            line =
                g_bcsv
                    ->bs_lines[((size_t)rej.i * CLI_CSV_BSPLINE_SIDE + (size_t)rej.j) * IT2N_FP_COUNT + (size_t)rej.fp];
        }
        if (rej.code == IT2N_ERR_RANGE && rej.ch >= 0 && strcmp(s->ops->kind, "modbus") == 0 && rej.lo > 0) {
            char v[48];
            cli_fmt_val(v, sizeof(v), rej.value, 6);
            snprintf(msg, sizeof(msg),
                     "%s:%lu: %s=%s is not a multiple of "
                     "1/%lld: the Modbus map carries %s x%lld as %s "
                     "(use --link for exact values) at (i=%d,j=%d,%s)",
                     name, line, it2n_ch_name((unsigned)rej.ch), v, (long long)rej.lo,
                     rej.hi ? "coordinates" : "memberships", (long long)rej.lo, rej.hi ? "i32" : "u16", rej.i, rej.j,
                     it2n_fp_name((unsigned)rej.fp));
            fprintf(stderr, "%s\n", msg);
            return CTL_EXIT_DATA;
        }
        cli_csv_locate(g_bds != NULL ? g_bcsv : &g_csv, &rej, &e);
        cli_csv_message(&e, name, msg, sizeof(msg));
        fprintf(stderr,
                "%s (refused by it2nd at %s; the model is left "
                "incomplete)\n",
                msg, s->where);
        return CTL_EXIT_DATA;
    }
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    rc = s->ops->status(s->c, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    printf("%s: pushed %u points to %s: %s, %ux%u grid, generation %lu\n", name, st.present, s->where,
           ctl_state_name(st.state), st.n + 1u, st.m + 1u, (unsigned long)st.generation);
    return cli_finish_output("it2nctl");
}

int ctl_cmd_eval(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    size_t k;
    int rc = ctl_solved_status(s, a, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    cli_put_header(&ctl_out, "u,w,footprint", ",out_of_range");
    for (k = 0; k < a->o.nat; k++) {
        it2n_par u = a->o.at[k].a, w = a->o.at[k].b;
        it2n_point pt;
        memset(&pt, 0, sizeof(pt));
        rc = s->ops->eval(s->c, &u, &w, &pt);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        cli_put_point(&ctl_out, u, w, &pt);
    }
    return cli_finish_output("it2nctl");
}

int ctl_cmd_locate(ctl_session *s, const ctl_args *a)
{
    static const char *const status[4] = {"inside", "outside", "noconv", "outside|noconv"};
    ctl_status st;
    ctl_loc res[IT2N_FP_COUNT];
    size_t k;
    unsigned fp;
    int rc = ctl_solved_status(s, a, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    printf("x,y,footprint,u,w%s,T,I,F,status\n", ctl_out.z ? ",z" : "");
    for (k = 0; k < a->o.nat; k++) {
        it2n_val x = a->o.at[k].a, y = a->o.at[k].b;
        rc = s->ops->locate(s->c, &x, &y, res);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            if (!has_fp(fp)) {
                continue;
            }
            const it2n_par uw[2] = {res[fp].u, res[fp].w};
            cli_put_locate_row(&ctl_out, x, y, fp, res[fp].has_uw ? uw : NULL, res[fp].v,
                               res[fp].status >= 0 && res[fp].status < 4 ? status[res[fp].status] : "?");
        }
    }
    return cli_finish_output("it2nctl");
}

static ctl_net g_net;

int ctl_cmd_net(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    unsigned i, j, fp;
    int rc = ctl_solved_status(s, a, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (st.kind != 0u) {
        fprintf(stderr,
                "it2nctl: %s: net prints a Bezier control net; this "
                "model is a B-spline (its coefficients: the "
                "coef_page/coef_window registers, docs/registers.md; "
                "'it2n solve --kind bspline' prints them from the CSV)\n",
                s->where);
        return CTL_EXIT_DATA;
    }
    rc = s->ops->net(s->c, &st, &g_net);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    cli_put_header(&ctl_out, "i,j,footprint", "");
    for (i = 0; i <= st.n; i++) {
        for (j = 0; j <= st.m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!has_fp(fp)) {
                    continue;
                }
                cli_put_net_row(&ctl_out, (int)i, (int)j, fp, g_net[fp][i][j]);
            }
        }
    }
    return cli_finish_output("it2nctl");
}

int ctl_cmd_sample(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    unsigned fp;
    int rc = ctl_solved_status(s, a, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if ((a->o.fpmask & (1u << fp)) && !has_fp(fp)) {
            fprintf(stderr,
                    "it2nctl: %s: --footprint %s: not in this type-1 model "
                    "(footprint D only)\n",
                    s->where, it2n_fp_name(fp));
            return CTL_EXIT_DATA;
        }
    }
    cli_put_header(&ctl_out, "u,w,footprint", ",out_of_range");
    rc = s->ops->sample(s->c, &st, a->o.rows, a->o.cols, cli_put_sample_row, &ctl_out);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    return cli_finish_output("it2nctl");
}
