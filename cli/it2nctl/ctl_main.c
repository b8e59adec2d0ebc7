/*
 * it2nctl — client for a running it2nd: push a dataset CSV, query, read the
 * control nets, watch and plot the live model, over Modbus TCP/RTU or the
 * framing protocol on a serial line. Output and errors follow it2n's
 * conventions (docs/cli.md): CSV on stdout with the same headers and exact
 * decimal text, FILE:LINE errors, exit 1 usage, 2 data, 3 connection.
 */
#include "cli.h"
#include "csv.h"
#include "ctl.h"
#include "out.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define CTL_GRID_DEFAULT 21u

/* it2nctl's own command bits (the shared ones, CLI_O_*: cli.h). */
enum {
    O_DATA = CLI_O_PROG,            /* DATA.csv operand          */
    O_COUNT = CLI_O_PROG << 1,      /* --count N                 */
    O_INCOMPLETE = CLI_O_PROG << 2, /* --incomplete              */
    O_FOLLOW = CLI_O_PROG << 3,     /* --follow                  */
    O_PLOT = CLI_O_PLOT | CLI_O_OUT | CLI_O_MEMB
};

typedef struct ctl_cmd {
    const char *name, *args, *summary, *help;
    unsigned opts;
} ctl_cmd;

static const ctl_cmd cmds[] = {
    {"status", "", "Print the model's state, degrees, points and generation",
     "One CSV row: model,state,n,m,type,coordinates,parameters,\n"
     "points_present,points_required,generation,last_error,kind. state is\n"
     "empty, incomplete, solved or failed; last_error an it2n error code\n"
     "(0 none); kind bezier or bspline (n, m: degrees or intervals).\n",
     0},
    {"push", "DATA.csv", "Configure the model, upload every point, commit",
     "Reads DATA.csv as 'it2n check' does (errors FILE:LINE, exit 2, nothing\n"
     "sent), then configures the model to the file's degrees and flags,\n"
     "clears it, uploads every point and commits (solves). A progress bar\n"
     "goes to standard error when it is a terminal. Over Modbus every value\n"
     "must be exact in the map's scaled integers (memberships x10000,\n"
     "coordinates x coord_scale); --link carries any value exactly.\n"
     "  --chord   chord-length parameters\n"
     "  --kind bezier|bspline\n"
     "            bspline: read DATA.csv for the cubic B-spline kind (grids up\n"
     "            to 256x256) and push it to a [model:ID] with kind = bspline\n"
     "            (over Modbus; the default is bezier)\n",
     O_DATA | CLI_O_CHORD | CLI_O_KIND},
    {"eval", "--at U,W [--at U,W ...]", "Evaluate every footprint at (u, w)",
     "As 'it2n eval', answered by the daemon: u,w,footprint,x,y[,z],T,I,F,\n"
     "out_of_range.\n"
     "  --at U,W    parameters in [0,1] (repeatable)\n"
     "  --summary   add upper/lower interval bound rows\n",
     CLI_O_AT_UW | CLI_O_SUMMARY},
    {"locate", "--at X,Y [--at X,Y ...]", "Find (u, w) of location (x, y)",
     "As 'it2n locate': x,y,footprint,u,w[,z],T,I,F,status. Over Modbus the\n"
     "register map carries no u, w (left empty) and one bit per footprint:\n"
     "status is inside or outside|noconv.\n"
     "  --at X,Y    location (repeatable)\n",
     CLI_O_AT_XY},
    {"net", "", "Print the solved control nets",
     "As 'it2n solve': i,j,footprint,x,y[,z],T,I,F.\n", 0},
    {"sample", "--grid RxC", "Evaluate on an RxC parameter grid",
     "As 'it2n sample': u = r/(R-1), w = c/(C-1), row-major.\n"
     "  --grid RxC          R, C in 2..65535\n"
     "  --summary           add interval bound rows\n"
     "  --footprint LIST    only these footprints\n",
     CLI_O_GRID | CLI_O_SUMMARY | CLI_O_FP},
    {"watch", "[--count N] [--incomplete]",
     "Print a status row for each new generation",
     "Prints the status row now and again whenever the model's generation\n"
     "changes (Modbus: polled every 100 ms; link: on the daemon's EVENTs).\n"
     "Rows are committed generations: a solved or failed model at once, an\n"
     "empty or incomplete one once it has stood for 1 s (a push in progress\n"
     "configures, clears and uploads before it commits: no rows).\n"
     "  --count N      stop after N rows (default: run until interrupted)\n"
     "  --incomplete   a row for every generation, a push's too\n",
     O_COUNT | O_INCOMPLETE},
    {"plot", "-o FILE.png|FILE.svg [--follow [--count N]]",
     "Draw the live model with gnuplot",
     "Reads the control nets and draws them with it2n plot's code: same\n"
     "options, colours and errors (see 'it2n plot --help'); the data points\n"
     "marked are the surfaces at the parameter nodes.\n"
     "  -o FILE            .png or .svg\n"
     "  --membership M     T, I, F or all (three panels; default)\n"
     "  --interval         upper/lower band of one membership\n"
     "  --nets             also draw the control nets\n"
     "  --grid RxC         2..1001 each (default 21x21; --interval 81x81)\n"
     "  --footprint LIST   only these footprints\n"
     "  --size WxH         200..8000 each (default by figure, see it2n)\n"
     "  --follow           draw again on every new solved generation (the\n"
     "                     file is replaced whole, never seen half written);\n"
     "                     one line 'generation G: FILE' per drawing\n"
     "  --count N          with --follow: stop after N drawings\n",
     O_PLOT | CLI_O_GRID_OPT | CLI_O_FP | O_COUNT | O_FOLLOW},
};
#define NCMDS (sizeof(cmds) / sizeof(cmds[0]))

/* it2nctl's own options; the labelled ones are the "Connection" list of
 * --help. */
enum {
    OPT_TCP = CLI_OPT_PROG, OPT_RTU, OPT_LINK, OPT_UNIT, OPT_MODEL, OPT_BAUD,
    OPT_PARITY, OPT_STOP, OPT_TIMEOUT, OPT_COUNT, OPT_FOLLOW, OPT_INCOMPLETE,
    OPT_BROKER, OPT_GROUP, OPT_NODE
};

static const cli_opt own_opts[] = {
    {"tcp", 0, CLI_ARG_TEXT, OPT_TCP, 0, 0, 0, NULL, NULL, NULL,
     "--tcp HOST[:PORT]", "Modbus TCP (PORT default 1502; [v6addr]:PORT)"},
    {"rtu", 0, CLI_ARG_TEXT, OPT_RTU, 0, 0, 0, NULL, NULL, NULL,
     "--rtu DEVICE", "Modbus RTU on a serial device"},
    {"baud", 0, CLI_ARG_UINT, OPT_BAUD, 0, 1200, 4000000, NULL,
     "expected 1200..4000000", NULL, "--baud N",
     "RTU (default 19200) or link (default 115200)"},
    {"parity", 0, CLI_ARG_WORD, OPT_PARITY, 0, 0, 0, "none|even|odd",
     "expected none, even or odd", NULL, "--parity none|even|odd",
     "RTU (default even), --stop-bits 1|2"},
    {"stop-bits", 0, CLI_ARG_UINT, OPT_STOP, 0, 1, 2, NULL, "expected 1 or 2",
     NULL, NULL, NULL},
    {"unit", 0, CLI_ARG_UINT, OPT_UNIT, 0, 0, 255, NULL, "expected 0..255",
     NULL, "--unit N",
     "Modbus unit id 0..255 (default 1; on TCP 0 and 255\n"
     "reach the default model)"},
    {"link", 0, CLI_ARG_TEXT, OPT_LINK, 0, 0, 0, NULL, NULL, NULL,
     "--link DEVICE",
     "framing protocol on a serial line or pty wired to\n"
     "one of the daemon's [link:] devices"},
    {"model", 0, CLI_ARG_UINT, OPT_MODEL, 0, 0, 254, NULL, "expected 0..254",
     NULL, "--model ID", "model id on a link, 0..254 (default 1)"},
    {"timeout", 0, CLI_ARG_UINT, OPT_TIMEOUT, 0, 10, 600000, NULL,
     "expected 10..600000 ms", NULL, "--timeout MS",
     "per request (default 3000)"},
    {"broker", 0, CLI_ARG_TEXT, OPT_BROKER, 0, 0, 0, NULL, NULL, NULL,
     "--broker HOST:PORT",
     "'it2nctl spb status|eval': through a Sparkplug B\n"
     "edge node's DCMD query on this MQTT broker (PORT\n"
     "default 1883), with --group G --node N; --model ID\n"
     "is the device model-ID (default 1)"},
    {"group", 0, CLI_ARG_TEXT, OPT_GROUP, 0, 0, 0, NULL, NULL, NULL, NULL,
     NULL},
    {"node", 0, CLI_ARG_TEXT, OPT_NODE, 0, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"count", 0, CLI_ARG_UINT, OPT_COUNT, O_COUNT, 1, 1000000000, NULL,
     "expected 1 or more", NULL, NULL, NULL},
    {"follow", 0, CLI_ARG_NONE, OPT_FOLLOW, O_FOLLOW, 0, 0, NULL, NULL, NULL,
     NULL, NULL},
    {"incomplete", 0, CLI_ARG_NONE, OPT_INCOMPLETE, O_INCOMPLETE, 0, 0, NULL,
     NULL, NULL, NULL, NULL},
};

static void conn_help(FILE *out)
{
    fputs("Connection (default Modbus TCP 127.0.0.1:1502, unit 1):\n", out);
    cli_opt_help(out, own_opts, sizeof(own_opts) / sizeof(own_opts[0]), 0u,
                 20u);
    fputs("Without --tcp, --rtu or --link: $IT2NCTL_TCP if set, else\n"
          "127.0.0.1:1502.\n"
          "Common: --decimals N (0..9, default 6), --help.\n"
          "Exit status: 0 ok, 1 usage error, 2 data error or refused by the\n"
          "daemon, 3 daemon unreachable or not answering.\n",
          out);
}

typedef struct ctl_args {
    const ctl_cmd *cmd;
    cli_opts o;            /* output options as it2n's            */
    ctl_conn_opts conn;
    unsigned count;        /* watch/plot --count, 0 = forever      */
    bool incomplete;       /* watch --incomplete                   */
    bool follow;           /* plot --follow                        */
} ctl_args;

static void usage_all(FILE *out)
{
    size_t k;
    fprintf(out, "Usage: it2nctl COMMAND [ARGS] [OPTIONS]\n"
                 "Client for a running it2nd (Modbus TCP/RTU or a protocol "
                 "link).\n\nCommands:\n");
    for (k = 0; k < NCMDS; k++) {
        fprintf(out, "  %-7s %s\n", cmds[k].name, cmds[k].summary);
    }
    fprintf(out, "  %-7s %s\n", "spb",
            "Sparkplug B host mode: spb watch, spb status, spb eval");
    fprintf(out, "\n'it2nctl COMMAND --help' for details; 'it2nctl "
                 "--version'.\n\n");
    conn_help(out);
}

static void usage_cmd(const ctl_cmd *c)
{
    printf("Usage: it2nctl %s%s%s [CONNECTION] [--decimals N]\n\n%s\n",
           c->name, c->args[0] ? " " : "", c->args, c->help);
    conn_help(stdout);
}

#define usage_error(...) cli_usage_error("it2nctl", __VA_ARGS__)

/* ---- output: it2n's rows (cli/common/out.c) ----------------------------- */

/* The rows' options, and the model's z and type once its status is read. */
static cli_out g_out;

static bool has_fp(unsigned fp)
{
    return cli_out_has_fp(&g_out, fp);
}

/* ---- shared helpers ----------------------------------------------------- */

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
            if (a < pt->sum.upper_min[k]) pt->sum.upper_min[k] = a;
            if (a > pt->sum.upper_max[k]) pt->sum.upper_max[k] = a;
            if (b < pt->sum.lower_min[k]) pt->sum.lower_min[k] = b;
            if (b > pt->sum.lower_max[k]) pt->sum.lower_max[k] = b;
        }
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            it2n_val v = pt->v[fp][ch];
            if ((type1 ? fp == IT2N_FP_D : true) &&
                (v < 0 || v > IT2N_VAL_ONE)) {
                pt->out_of_range |= (uint32_t)1u << (fp * 3u + k);
            }
        }
    }
}

typedef struct ctl_session {
    void *c;
    const ctl_ops *ops;
    const char *where; /* for messages */
    char wbuf[200];
} ctl_session;

static int open_session(const ctl_args *a, ctl_session *s)
{
    int rc = CTL_EXIT_OK;
    if (a->conn.broker != NULL) {
        s->c = ctl_spb_open(&a->conn, &s->ops, &rc);
        snprintf(s->wbuf, sizeof(s->wbuf), "%s/%s model-%u", a->conn.group,
                 a->conn.node, a->conn.model);
    } else if (a->conn.link != NULL) {
        s->c = ctl_link_open(&a->conn, &s->ops, &rc);
        snprintf(s->wbuf, sizeof(s->wbuf), "%s model %u", a->conn.link,
                 a->conn.model);
    } else {
        s->c = ctl_modbus_open(&a->conn, &s->ops, &rc);
        if (a->conn.rtu != NULL) {
            snprintf(s->wbuf, sizeof(s->wbuf), "%s unit %u", a->conn.rtu,
                     a->conn.unit);
        } else {
            snprintf(s->wbuf, sizeof(s->wbuf), "%s unit %u",
                     a->conn.tcp ? a->conn.tcp : "127.0.0.1:1502",
                     a->conn.unit);
        }
    }
    s->where = s->wbuf;
    return s->c == NULL ? rc : CTL_EXIT_OK;
}

/* Status, and the model must be solved for queries. */
static int solved_status(ctl_session *s, ctl_status *st)
{
    int rc = s->ops->status(s->c, st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    g_out.z = (st->flags & IT2N_F_Z) != 0u;
    g_out.type1 = (st->flags & IT2N_F_TYPE1) != 0u;
    if (st->state != CTL_ST_SOLVED) {
        fprintf(stderr,
                "it2nctl: %s: the model is not solved (state %s, %u of %u "
                "points%s)\n",
                s->where, ctl_state_name(st->state), st->present,
                st->required,
                st->state == CTL_ST_FAILED ? "; see last_error in status"
                                           : "");
        return CTL_EXIT_DATA;
    }
    return CTL_EXIT_OK;
}

/* ---- commands ----------------------------------------------------------- */

static void put_status_header(void)
{
    puts("model,state,n,m,type,coordinates,parameters,points_present,"
         "points_required,generation,last_error,kind");
}

static void put_status_row(const ctl_status *st)
{
    printf("%u,%s,%u,%u,%s,%s,%s,%u,%u,%lu,%d,%s\n", st->model,
           ctl_state_name(st->state), st->n, st->m,
           (st->flags & IT2N_F_TYPE1) ? "type-1" : "type-2",
           (st->flags & IT2N_F_Z) ? "xyz" : "xy",
           (st->flags & IT2N_F_CHORD) ? "chord-length" : "uniform",
           st->present, st->required, (unsigned long)st->generation,
           st->last_error, st->kind ? "bspline" : "bezier");
}

static int cmd_status(ctl_session *s)
{
    ctl_status st;
    int rc = s->ops->status(s->c, &st);
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
static int next_generation(ctl_session *s, bool every, uint32_t gen,
                           ctl_status *st)
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
        if (every || st->state == CTL_ST_SOLVED ||
            st->state == CTL_ST_FAILED) {
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
                left = WATCH_SETTLE_MS - ((t.tv_sec - t0.tv_sec) * 1000L +
                                          (t.tv_nsec - t0.tv_nsec) / 1000000L);
            }
        }
        if (st->generation == gen) {
            return CTL_EXIT_OK; /* settled */
        }
        gen = st->generation - 1u; /* moved on: judge the new one */
    }
}

static int cmd_watch(ctl_session *s, const ctl_args *a)
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
        rc = next_generation(s, a->incomplete, gen, &st);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
    }
}

static it2n_csv g_csv;
static it2n_dataset g_ds;
static it2n_model g_mdl;

/* Read, check and solve DATA.csv exactly as it2n does (the same code). */
static const it2n_bspline_data *g_bds;  /* push --kind bspline */
static const it2n_csv *g_bcsv;

static int load(const cli_opts *o)
{
    if (o->kind == CLI_KIND_BSPLINE) {
        const it2n_bspline_model *bm;
        if (o->flags & IT2N_F_CHORD) {
            fprintf(stderr, "it2nctl push: --chord: the B-spline kind has "
                            "uniform parameters only\n");
            return CTL_EXIT_USAGE;
        }
        return cli_load_bspline(o, &g_bds, &bm, &g_bcsv) == CLI_EXIT_OK
                   ? CTL_EXIT_OK : CTL_EXIT_DATA;
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

static int cmd_push(ctl_session *s, const ctl_args *a)
{
    const char *name = cli_display_name(a->o.path);
    it2n_errinfo rej;
    ctl_status st;
    char msg[600];
    int rc;
    if (g_bds != NULL && s->ops->push_bspline == NULL) {
        fprintf(stderr, "it2nctl: push --kind bspline: not over --%s (its "
                        "messages carry Bezier degrees up to %d); push over "
                        "Modbus (--tcp or --rtu)\n",
                s->ops->kind, IT2N_MAX_DEGREE);
        return CTL_EXIT_USAGE;
    }
    rc = g_bds != NULL ? s->ops->push_bspline(s->c, g_bds, isatty(2) ? progress_bar : NULL, NULL, &rej)
                       : s->ops->push(s->c, &g_ds, isatty(2) ? progress_bar : NULL, NULL, &rej);
    if (g_bar_open) { /* failed midway: the message on its own line */
        fputc('\n', stderr);
        g_bar_open = false;
    }
    if (rc == CTL_REJECTED) {
        it2n_csv_error e;
        unsigned long line = 0;
        if (rej.i >= 0 && rej.j >= 0 && rej.fp >= 0 && rej.i < IT2N_DIM &&
            rej.j < IT2N_DIM && rej.fp < IT2N_FP_COUNT) {
            line = g_csv.lines[rej.i][rej.j][rej.fp];
        }
        if (g_bds != NULL && rej.i >= 0 && rej.j >= 0 && rej.fp >= 0 &&
            rej.i <= IT2N_BSPLINE_MAX_N && rej.j <= IT2N_BSPLINE_MAX_N &&
            rej.fp < IT2N_FP_COUNT) {
            line = g_bcsv->bs_lines[((size_t)rej.i * IT2N_CSV_BSPLINE_SIDE + (size_t)rej.j) * IT2N_FP_COUNT +
                                    (size_t)rej.fp];
        }
        if (rej.code == IT2N_ERR_RANGE && rej.ch >= 0 &&
            strcmp(s->ops->kind, "modbus") == 0 && rej.lo > 0) {
            char v[48];
            cli_fmt_val(v, sizeof(v), rej.value, 6);
            snprintf(msg, sizeof(msg), "%s:%lu: %s=%s is not a multiple of "
                     "1/%lld: the Modbus map carries %s x%lld as %s "
                     "(use --link for exact values) at (i=%d,j=%d,%s)",
                     name, line, it2n_ch_name((unsigned)rej.ch), v,
                     (long long)rej.lo,
                     rej.hi ? "coordinates" : "memberships",
                     (long long)rej.lo, rej.hi ? "i32" : "u16", rej.i, rej.j,
                     it2n_fp_name((unsigned)rej.fp));
            fprintf(stderr, "%s\n", msg);
            return CTL_EXIT_DATA;
        }
        it2n_csv_locate(g_bds != NULL ? g_bcsv : &g_csv, &rej, &e);
        it2n_csv_message(&e, name, msg, sizeof(msg));
        fprintf(stderr, "%s (refused by it2nd at %s; the model is left "
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
    printf("%s: pushed %u points to %s: %s, %ux%u grid, generation %lu\n",
           name, st.present, s->where, ctl_state_name(st.state), st.n + 1u,
           st.m + 1u, (unsigned long)st.generation);
    return cli_finish_output("it2nctl");
}

static int cmd_eval(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    size_t k;
    int rc = solved_status(s, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    cli_put_header(&g_out, "u,w,footprint", ",out_of_range");
    for (k = 0; k < a->o.nat; k++) {
        it2n_par u = a->o.at[k].a, w = a->o.at[k].b;
        it2n_point pt;
        memset(&pt, 0, sizeof(pt));
        rc = s->ops->eval(s->c, &u, &w, &pt);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        cli_put_point(&g_out, u, w, &pt);
    }
    return cli_finish_output("it2nctl");
}

static int cmd_locate(ctl_session *s, const ctl_args *a)
{
    static const char *const status[4] = {"inside", "outside", "noconv",
                                          "outside|noconv"};
    ctl_status st;
    ctl_loc res[IT2N_FP_COUNT];
    size_t k;
    unsigned fp;
    int rc = solved_status(s, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    printf("x,y,footprint,u,w%s,T,I,F,status\n", g_out.z ? ",z" : "");
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
            cli_put_locate_row(&g_out, x, y, fp, res[fp].has_uw ? uw : NULL,
                               res[fp].v,
                               res[fp].status >= 0 && res[fp].status < 4
                                   ? status[res[fp].status]
                                   : "?");
        }
    }
    return cli_finish_output("it2nctl");
}

static ctl_net g_net;

static int cmd_net(ctl_session *s)
{
    ctl_status st;
    unsigned i, j, fp;
    int rc = solved_status(s, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (st.kind != 0u) {
        fprintf(stderr, "it2nctl: %s: net prints a Bezier control net; this "
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
    cli_put_header(&g_out, "i,j,footprint", "");
    for (i = 0; i <= st.n; i++) {
        for (j = 0; j <= st.m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!has_fp(fp)) {
                    continue;
                }
                cli_put_net_row(&g_out, (int)i, (int)j, fp, g_net[fp][i][j]);
            }
        }
    }
    return cli_finish_output("it2nctl");
}

static int sample_row(void *ctx, unsigned r, unsigned c, it2n_par u,
                      it2n_par w, const it2n_point *pt)
{
    (void)r;
    (void)c;
    (void)ctx;
    cli_put_point(&g_out, u, w, pt);
    return ferror(stdout) ? CTL_EXIT_DATA : 0;
}

static int cmd_sample(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    unsigned fp;
    int rc = solved_status(s, &st);
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
    cli_put_header(&g_out, "u,w,footprint", ",out_of_range");
    rc = s->ops->sample(s->c, &st, a->o.rows, a->o.cols, sample_row,
                        (void *)&a->o);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    return cli_finish_output("it2nctl");
}

static unsigned bitlen64(uint64_t v)
{
    unsigned n = 0;
    while (v != 0u) {
        n++;
        v >>= 1;
    }
    return n;
}

/* The live model for plotting: the control nets (Q24) in the core's block
 * floating point, each net's largest point with 30 significant bits. */
static void net_to_model(const ctl_status *st, ctl_net *net,
                         it2n_model *mdl)
{
    unsigned fp, ch, i, j;
    memset(mdl, 0, sizeof(*mdl));
    mdl->n = (uint8_t)st->n;
    mdl->m = (uint8_t)st->m;
    mdl->flags = (uint8_t)st->flags;
    mdl->solved = 1;
    mdl->generation = st->generation;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            uint64_t big = 0;
            int s;
            for (i = 0; i <= st->n; i++) {
                for (j = 0; j <= st->m; j++) {
                    it2n_val v = (*net)[fp][i][j][ch];
                    uint64_t a = v < 0 ? (uint64_t)0 - (uint64_t)v
                                       : (uint64_t)v;
                    big = a > big ? a : big;
                }
            }
            s = (int)bitlen64(big) - 30;
            mdl->frac[fp][ch] = (int8_t)(IT2N_VAL_FRAC - s);
            for (i = 0; i <= st->n; i++) {
                for (j = 0; j <= st->m; j++) {
                    it2n_val v = (*net)[fp][i][j][ch];
                    int64_t q = s > 0 ? (v + ((int64_t)1 << (s - 1))) >> s
                                      : v * ((int64_t)1 << -s);
                    mdl->net[fp][ch][i * (st->m + 1u) + j] = (int32_t)q;
                }
            }
        }
    }
}

/* The live B-spline model for plotting: every net read row by row through
 * the coefficient page, each in block floating point as net_to_model. The
 * coefficients are the map's float32 (24 significant bits): close to the
 * daemon's surface, enough for a drawing. */
static int32_t *g_bcoef;
static it2n_bspline_model g_bmdl;

static int coef_to_model(ctl_session *s, const ctl_status *st)
{
    unsigned rows = st->net_rows, cols = st->net_cols, fp, ch, r, k;
    size_t size = (size_t)rows * cols, words;
    unsigned nch = (st->flags & IT2N_F_Z) ? 6u : 5u;
    it2n_val *v;
    if (s->ops->coef_row == NULL) {
        fprintf(stderr, "it2nctl: %s: a B-spline model's coefficients are "
                        "read over Modbus (--tcp or --rtu), not --%s\n",
                s->where, s->ops->kind);
        return CTL_EXIT_USAGE;
    }
    if (rows < 4u || cols < 4u || rows != st->n + 3u || cols != st->m + 3u) {
        fprintf(stderr, "it2nctl: %s: net of %ux%u for a %ux%u B-spline "
                        "model\n", s->where, rows, cols, st->n, st->m);
        return CTL_EXIT_DATA;
    }
    words = IT2N_BSPLINE_MODEL_WORDS(st->n, st->m, st->flags);
    free(g_bcoef);
    g_bcoef = malloc(words * sizeof(*g_bcoef));
    v = malloc(size * sizeof(*v));
    if (g_bcoef == NULL || v == NULL) {
        free(v);
        fprintf(stderr, "it2nctl: out of memory for a %ux%u net\n", rows, cols);
        return CTL_EXIT_DATA;
    }
    memset(&g_bmdl, 0, sizeof(g_bmdl));
    g_bmdl.coef = g_bcoef;
    g_bmdl.cap = words;
    g_bmdl.n = (uint16_t)st->n;
    g_bmdl.m = (uint16_t)st->m;
    g_bmdl.flags = (uint8_t)st->flags;
    g_bmdl.solved = 1;
    g_bmdl.generation = st->generation;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        unsigned slot = (st->flags & IT2N_F_TYPE1) ? 0u : fp, c = 0;
        if ((st->flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            uint64_t big = 0;
            int sh;
            int32_t *net;
            if (ch == IT2N_CH_Z && !(st->flags & IT2N_F_Z)) {
                continue;
            }
            for (r = 0; r < rows; r++) {
                int rc = s->ops->coef_row(s->c, st, fp, ch, r, &v[(size_t)r * cols]);
                if (rc != CTL_EXIT_OK) {
                    free(v);
                    return rc;
                }
            }
            for (k = 0; k < size; k++) {
                uint64_t a = v[k] < 0 ? (uint64_t)0 - (uint64_t)v[k] : (uint64_t)v[k];
                big = a > big ? a : big;
            }
            sh = (int)bitlen64(big) - 30;
            g_bmdl.frac[fp][ch] = (int8_t)(IT2N_VAL_FRAC - sh);
            net = g_bcoef + ((size_t)slot * nch + c) * size;
            for (k = 0; k < size; k++) {
                net[k] = (int32_t)(sh > 0 ? (v[k] + ((int64_t)1 << (sh - 1))) >> sh
                                          : v[k] * ((int64_t)1 << -sh));
            }
            c++;
        }
    }
    free(v);
    return CTL_EXIT_OK;
}

/* Draw the model described by st (already read, solved) into o->output. */
static int draw_live(ctl_session *s, const ctl_args *a, const ctl_status *st,
                     const char *output)
{
    cli_opts o = a->o;
    char title[256];
    cli_surface sf;
    int rc;
    memset(&sf, 0, sizeof(sf));
    if (st->kind == 1u) {
        rc = coef_to_model(s, st);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        sf.bsp = &g_bmdl;
    } else {
        rc = s->ops->net(s->c, st, &g_net);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        net_to_model(st, &g_net, &g_mdl);
        sf.bez = &g_mdl;
    }
    /* The title names the source: no '/' so it is printed whole. */
    snprintf(title, sizeof(title), "it2nd %s %u generation %lu",
             a->conn.link != NULL ? "model" : "unit",
             a->conn.link != NULL ? a->conn.model : a->conn.unit,
             (unsigned long)st->generation);
    o.path = title;
    o.output = output;
    return cli_plot(&o, &sf);
}

/* --follow: each drawing goes to a hidden file beside FILE, renamed over it
 * when complete, so a viewer reloading FILE never reads half an image. */
static int follow_plot(ctl_session *s, const ctl_args *a, ctl_status *st)
{
    const char *out = a->o.output, *base = strrchr(out, '/');
    char tmp[4200];
    unsigned drawn = 0;
    int rc;

    base = base ? base + 1 : out;
    snprintf(tmp, sizeof(tmp), "%.*s.%s.part%s", (int)(base - out), out, base,
             strrchr(base, '.'));
    for (;;) {
        rc = draw_live(s, a, st, tmp);
        if (rc == CTL_EXIT_OK && rename(tmp, out) != 0) {
            fprintf(stderr, "it2nctl: cannot replace %s: %s\n", out,
                    strerror(errno));
            unlink(tmp);
            rc = CTL_EXIT_DATA;
        }
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        printf("generation %lu: %s\n", (unsigned long)st->generation, out);
        fflush(stdout);
        if (a->count != 0u && ++drawn >= a->count) {
            return cli_finish_output("it2nctl");
        }
        do { /* the next solved generation; pushes in progress skipped */
            rc = next_generation(s, false, st->generation, st);
            if (rc != CTL_EXIT_OK) {
                return rc;
            }
        } while (st->state != CTL_ST_SOLVED);
    }
}

static int cmd_plot(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    int rc = solved_status(s, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (a->o.interval && g_out.type1) {
        fprintf(stderr, "it2nctl: %s: --interval needs a type-2 model\n",
                s->where);
        return CTL_EXIT_DATA;
    }
    return a->follow ? follow_plot(s, a, &st)
                     : draw_live(s, a, &st, a->o.output);
}

/* ---- options ------------------------------------------------------------ */

static const ctl_cmd *find_cmd(const char *name)
{
    size_t k;
    for (k = 0; k < NCMDS; k++) {
        if (strcmp(cmds[k].name, name) == 0) {
            return &cmds[k];
        }
    }
    return NULL;
}

/* Options may come before the command (it2nctl --tcp H:P status): the
 * first word that is not an option or an option's value is moved to the
 * front, the rest keep their order. Returns -1, or an exit status. */
static int command_first(int argc, char **argv)
{
    const cli_optset sets[2] = {cli_common_opts, CLI_OPTSET(own_opts)};
    char *cmd;
    int i = 1;
    while (i < argc && argv[i][0] == '-') {
        const cli_opt *lo = NULL;
        if (argv[i][1] == '-' && strchr(argv[i], '=') == NULL) {
            lo = cli_opt_find(sets, 2, argv[i] + 2);
        }
        i += (lo != NULL && lo->arg != CLI_ARG_NONE) ||
                     strcmp(argv[i], "-o") == 0
                 ? 2
                 : 1;
    }
    if (i >= argc) {
        return usage_error(NULL, "%s", "no command given (it may stand "
                                       "before or after the options)");
    }
    cmd = argv[i];
    memmove(&argv[2], &argv[1], (size_t)(i - 1) * sizeof(argv[0]));
    argv[1] = cmd;
    return -1;
}

/* --help, --version and the command word into a->cmd; -1 to go on. */
static int first_word(int argc, char **argv, ctl_args *a)
{
    const char *names[NCMDS + 1u], *near;
    const ctl_cmd *c;
    size_t k;
    int rc;
    if (argc < 2) {
        usage_all(stderr);
        return CTL_EXIT_USAGE;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
        strcmp(argv[1], "help") == 0) {
        if (argc > 2 && (c = find_cmd(argv[2])) != NULL) {
            usage_cmd(c);
        } else {
            usage_all(stdout);
        }
        return CTL_EXIT_OK;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("it2nctl %s (IT2N_MAX_DEGREE %d)\n", IT2N_CLI_VERSION,
               IT2N_MAX_DEGREE);
        return CTL_EXIT_OK;
    }
    if (argv[1][0] == '-' && (rc = command_first(argc, argv)) >= 0) {
        return rc;
    }
    a->cmd = find_cmd(argv[1]);
    if (a->cmd == NULL) {
        for (k = 0; k < NCMDS; k++) {
            names[k] = cmds[k].name;
        }
        names[NCMDS] = "spb";
        near = cli_did_you_mean(argv[1], names, NCMDS + 1u);
        return near ? usage_error(NULL, "unknown command '%s' (did you mean '%s'?)",
                                  argv[1], near)
                    : usage_error(NULL, "unknown command '%s'", argv[1]);
    }
    a->o.cmd = a->cmd->name;
    return -1;
}

/* One of it2nctl's own options into a; -1, or an exit status. */
static int take_own(const cli_parser *p, const cli_optval *v, ctl_args *a)
{
    static const char parity[3] = {'N', 'E', 'O'};
    char host[128], port[16];
    const char *bad;
    switch (v->opt->id) {
    case OPT_TCP:
        bad = ctl_tcp_split(v->text, host, sizeof(host), port, sizeof(port));
        if (bad != NULL) {
            return usage_error(p->cmd, "--tcp '%.200s': %s", v->text, bad);
        }
        a->conn.tcp = v->text;
        break;
    case OPT_RTU: a->conn.rtu = v->text; break;
    case OPT_LINK: a->conn.link = v->text; break;
    case OPT_UNIT: a->conn.unit = (unsigned)v->num; break;
    case OPT_MODEL: a->conn.model = (unsigned)v->num; break;
    case OPT_BAUD: a->conn.baud = (unsigned)v->num; break;
    case OPT_PARITY: a->conn.parity = parity[v->num]; break;
    case OPT_STOP: a->conn.stop_bits = (unsigned)v->num; break;
    case OPT_TIMEOUT: a->conn.timeout_ms = (unsigned)v->num; break;
    case OPT_COUNT: a->count = (unsigned)v->num; break;
    case OPT_FOLLOW: a->follow = true; break;
    case OPT_INCOMPLETE: a->incomplete = true; break;
    case OPT_BROKER: a->conn.broker = v->text; break; /* it2nctl spb */
    case OPT_GROUP: a->conn.group = v->text; break;
    case OPT_NODE: a->conn.node = v->text; break;
    default: break;
    }
    return -1;
}

/* One transport at most; $IT2NCTL_TCP; RTU unit ids; the baud default. */
static int finish_conn(const cli_parser *p, ctl_args *a)
{
    int nconn = cli_opt_seen(p, OPT_TCP) + cli_opt_seen(p, OPT_RTU) +
                cli_opt_seen(p, OPT_LINK) + cli_opt_seen(p, OPT_BROKER);
    const char *env = getenv("IT2NCTL_TCP");
    if (nconn > 1) {
        return usage_error(p->cmd, "%s", "give one of --tcp, --rtu and --link");
    }
    if (nconn == 0 && env != NULL && env[0] != '\0') {
        char host[128], port[16];
        const char *bad = ctl_tcp_split(env, host, sizeof(host), port,
                                        sizeof(port));
        a->conn.tcp = env;
        if (bad != NULL) {
            return usage_error(p->cmd, "IT2NCTL_TCP='%.200s': %s", env, bad);
        }
    }
    if (a->conn.rtu != NULL && a->conn.unit > 247) {
        return usage_error(p->cmd, "%s",
                           "--unit: RTU unit ids are 0..247 (248..255 are "
                           "reserved on a serial line; 255 reaches the "
                           "default model on TCP only)");
    }
    if (!cli_opt_seen(p, OPT_BAUD)) {
        a->conn.baud = a->conn.link != NULL ? 115200u : 19200u;
    }
    return -1;
}

/* Parse argv into a; returns -1 to go on, else an exit status. */
static int parse_args(int argc, char **argv, ctl_args *a)
{
    const cli_optset sets[2] = {cli_common_opts, CLI_OPTSET(own_opts)};
    const ctl_cmd *c;
    cli_parser p;
    cli_optval v;
    char **ops;
    int id, nops, rc = first_word(argc, argv, a);
    if (rc >= 0) {
        return rc;
    }
    c = a->cmd;
    cli_opt_init(&p, "it2nctl", c->name, c->opts, sets, 2, argc, argv, 2);
    while ((id = cli_opt_next(&p, &v)) != CLI_OPT_END) {
        if (id == CLI_OPT_ERROR) {
            return CTL_EXIT_USAGE;
        } else if (id == CLI_OPT_HELP) {
            usage_cmd(c);
            return CTL_EXIT_OK;
        } else if (id == CLI_OPT_VERSION) {
            printf("it2nctl %s\n", IT2N_CLI_VERSION);
            return CTL_EXIT_OK;
        }
        rc = id >= CLI_OPT_PROG ? take_own(&p, &v, a)
                                : cli_common_take(&p, &v, &a->o);
        if (rc >= 0) {
            return rc;
        }
    }
    if ((rc = finish_conn(&p, a)) >= 0) {
        return rc;
    }
    nops = cli_opt_operands(&p, &ops);
    if ((c->opts & O_DATA) && nops != 1) {
        return usage_error(c->name, "%s", nops == 0 ? "missing DATA.csv"
                                                    : "expected exactly one DATA.csv");
    }
    if (!(c->opts & O_DATA) && nops != 0) {
        return usage_error(c->name, "unexpected argument '%s'", ops[0]);
    }
    a->o.path = (c->opts & O_DATA) ? ops[0] : NULL;
    if ((c->opts & O_FOLLOW) && a->count != 0u && !a->follow) {
        return usage_error(c->name, "%s", "--count needs --follow");
    }
    return cli_common_finish(&p, &a->o);
}

/* `it2nctl spb watch ...` runs here; `it2nctl spb status|eval ...` go on
 * as status and eval with the Sparkplug transport (argv without "spb").
 * Returns an exit status, or -1 to go on. */
static int ctl_spb_args(int *argc, char ***argv)
{
    if (*argc > 2 && strcmp((*argv)[2], "watch") == 0) {
        return ctl_spb_watch(*argc - 2, *argv + 2);
    }
    if (*argc == 3 && (strcmp((*argv)[2], "--help") == 0 ||
                       strcmp((*argv)[2], "-h") == 0)) {
        printf("Usage: it2nctl spb watch --broker HOST:PORT --group G "
               "[--node N] [--count N]\n"
               "       it2nctl spb status|eval --broker HOST:PORT --group G "
               "--node N [--model ID] ...\n\n"
               "A Sparkplug B host application (docs/sparkplug.md):\n"
               "  --broker HOST:PORT   MQTT broker (PORT default 1883)\n"
               "  --group G            Sparkplug group_id\n"
               "  --node N             Sparkplug edge_node_id\n"
               "  --model ID           device model-ID (default 1)\n"
               "'watch' prints births and deaths as CSV lines; 'status' and "
               "'eval' print\nwhat 'it2nctl status' and 'it2nctl eval' "
               "print, through the device's DCMD\nquery ('it2nctl spb watch "
               "--help', 'it2nctl eval --help').\n");
        return CTL_EXIT_OK;
    }
    if (*argc < 3 || (strcmp((*argv)[2], "eval") != 0 &&
                      strcmp((*argv)[2], "status") != 0)) {
        fprintf(stderr, "it2nctl: spb: expected watch, status or eval\n"
                        "Try 'it2nctl spb watch --help', "
                        "'it2nctl spb eval --help'.\n");
        return CTL_EXIT_USAGE;
    }
    (*argv)[1] = (char *)"spb"; /* argv[0] of the rest: only in messages */
    (*argv)++;
    (*argc)--;
    return -1;
}

/* --broker, --group, --node: all three, with spb, and only there. */
static int ctl_spb_check(const ctl_args *a, const char *argv0)
{
    bool spb = strcmp(argv0, "spb") == 0;
    if (!spb && (a->conn.broker || a->conn.group || a->conn.node)) {
        return usage_error(a->cmd->name, "%s",
                           "--broker, --group and --node belong to "
                           "'it2nctl spb status|eval'");
    }
    if (spb && (!a->conn.broker || !a->conn.group || !a->conn.node)) {
        return usage_error(a->cmd->name, "%s",
                           "it2nctl spb needs --broker HOST:PORT, --group G "
                           "and --node N (and --model N, default 1)");
    }
    return -1;
}

int main(int argc, char **argv)
{
    ctl_args a;
    ctl_session s;
    int rc;
    memset(&a, 0, sizeof(a));
    memset(&s, 0, sizeof(s));
    cli_opts_init(&a.o);
    a.conn.unit = 1;
    a.conn.model = 1;
    a.conn.parity = 'E';
    a.conn.stop_bits = 1;
    a.conn.timeout_ms = 3000;
    if (argc > 1 && strcmp(argv[1], "spb") == 0) {
        rc = ctl_spb_args(&argc, &argv);
        if (rc >= 0) {
            return rc;
        }
    }
    rc = parse_args(argc, argv, &a);
    cli_out_init(&g_out, 0u, a.o.decimals, a.o.fpmask, a.o.summary);
    if (rc < 0) {
        rc = ctl_spb_check(&a, argv[0]);
    }
    if (rc >= 0) {
        free(a.o.at);
        return rc;
    }
    /* Bad data is reported before the daemon is contacted. */
    if (a.cmd->opts & O_DATA) {
        rc = load(&a.o);
        if (rc != CTL_EXIT_OK) {
            free(a.o.at);
            return rc;
        }
    }
    rc = open_session(&a, &s);
    if (rc != CTL_EXIT_OK) {
        free(a.o.at);
        return rc;
    }
    if (strcmp(a.cmd->name, "status") == 0) {
        rc = cmd_status(&s);
    } else if (strcmp(a.cmd->name, "push") == 0) {
        rc = cmd_push(&s, &a);
    } else if (strcmp(a.cmd->name, "eval") == 0) {
        rc = cmd_eval(&s, &a);
    } else if (strcmp(a.cmd->name, "locate") == 0) {
        rc = cmd_locate(&s, &a);
    } else if (strcmp(a.cmd->name, "net") == 0) {
        rc = cmd_net(&s);
    } else if (strcmp(a.cmd->name, "sample") == 0) {
        rc = cmd_sample(&s, &a);
    } else if (strcmp(a.cmd->name, "watch") == 0) {
        rc = cmd_watch(&s, &a);
    } else {
        rc = cmd_plot(&s, &a);
    }
    s.ops->close(s.c);
    free(a.o.at);
    cli_free_bspline();
    return rc;
}
