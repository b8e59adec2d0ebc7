/*
 * it2nctl — client for a running it2nd: push a dataset CSV, query, read the
 * control nets, watch and plot the live model, over Modbus TCP/RTU or the
 * framing protocol on a serial line. Output and errors follow it2n's
 * conventions (docs/cli.md): CSV on stdout with the same headers and exact
 * decimal text, FILE:LINE errors, exit 1 usage, 2 data, 3 connection.
 */
#include "cli.h"
#include "ctl.h"
#include "ctl_cmds.h"
#include "out.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* it2nctl's own command bits (the shared ones, CLI_O_*: cli.h). */
enum {
    O_DATA = CLI_O_PROG,            /* DATA.csv operand          */
    O_COUNT = CLI_O_PROG << 1,      /* --count N                 */
    O_INCOMPLETE = CLI_O_PROG << 2, /* --incomplete              */
    O_FOLLOW = CLI_O_PROG << 3,     /* --follow                  */
    O_PLOT = CLI_O_PLOT | CLI_O_OUT | CLI_O_MEMB
};

static const ctl_cmd cmds[] = {
    {{"status", "", "Print the model's state, degrees, points and generation",
      "One CSV row: model,state,n,m,type,coordinates,parameters,\n"
      "points_present,points_required,generation,last_error,kind. state is\n"
      "empty, incomplete, solved or failed; last_error an it2n error code\n"
      "(0 none); kind bezier or bspline (n, m: degrees or intervals).\n"},
     0,
     ctl_cmd_status},
    {{"push", "DATA.csv", "Configure the model, upload every point, commit",
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
      "            (over Modbus; the default is bezier)\n"},
     O_DATA | CLI_O_CHORD | CLI_O_KIND,
     ctl_cmd_push},
    {{"eval", "--at U,W [--at U,W ...]", "Evaluate every footprint at (u, w)",
      "As 'it2n eval', answered by the daemon: u,w,footprint,x,y[,z],T,I,F,\n"
      "out_of_range.\n"
      "  --at U,W    parameters in [0,1] (repeatable)\n"
      "  --summary   add upper/lower interval bound rows\n"},
     CLI_O_AT_UW | CLI_O_SUMMARY,
     ctl_cmd_eval},
    {{"locate", "--at X,Y [--at X,Y ...]", "Find (u, w) of location (x, y)",
      "As 'it2n locate': x,y,footprint,u,w[,z],T,I,F,status. Over Modbus the\n"
      "register map carries no u, w (left empty) and one bit per footprint:\n"
      "status is inside or outside|noconv.\n"
      "  --at X,Y    location (repeatable)\n"},
     CLI_O_AT_XY,
     ctl_cmd_locate},
    {{"net", "", "Print the solved control nets", "As 'it2n solve': i,j,footprint,x,y[,z],T,I,F.\n"}, 0, ctl_cmd_net},
    {{"sample", "--grid RxC", "Evaluate on an RxC parameter grid",
      "As 'it2n sample': u = r/(R-1), w = c/(C-1), row-major.\n"
      "  --grid RxC          R, C in 2..65535\n"
      "  --summary           add interval bound rows\n"
      "  --footprint LIST    only these footprints\n"},
     CLI_O_GRID | CLI_O_SUMMARY | CLI_O_FP,
     ctl_cmd_sample},
    {{"watch", "[--count N] [--incomplete]", "Print a status row for each new generation",
      "Prints the status row now and again whenever the model's generation\n"
      "changes (Modbus: polled every 100 ms; link: on the daemon's EVENTs).\n"
      "Rows are committed generations: a solved or failed model at once, an\n"
      "empty or incomplete one once it has stood for 1 s (a push in progress\n"
      "configures, clears and uploads before it commits: no rows).\n"
      "  --count N      stop after N rows (default: run until interrupted)\n"
      "  --incomplete   a row for every generation, a push's too\n"},
     O_COUNT | O_INCOMPLETE,
     ctl_cmd_watch},
    {{"plot", "-o FILE.png|FILE.svg [--follow [--count N]]", "Draw the live model with gnuplot",
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
      "  --count N          with --follow: stop after N drawings\n"},
     O_PLOT | CLI_O_GRID_OPT | CLI_O_FP | O_COUNT | O_FOLLOW,
     ctl_cmd_plot},
};
#define NCMDS (sizeof(cmds) / sizeof(cmds[0]))

/* it2nctl's own options; the labelled ones are the "Connection" list of
 * --help. */
enum {
    OPT_TCP = CLI_OPT_PROG,
    OPT_RTU,
    OPT_LINK,
    OPT_UNIT,
    OPT_MODEL,
    OPT_BAUD,
    OPT_PARITY,
    OPT_STOP,
    OPT_TIMEOUT,
    OPT_COUNT,
    OPT_FOLLOW,
    OPT_INCOMPLETE,
    OPT_BROKER,
    OPT_GROUP,
    OPT_NODE
};

static const cli_opt own_opts[] = {
    {"tcp", 0, CLI_ARG_TEXT, OPT_TCP, 0, 0, 0, NULL, NULL, NULL, "--tcp HOST[:PORT]",
     "Modbus TCP (PORT default 1502; [v6addr]:PORT)"},
    {"rtu", 0, CLI_ARG_TEXT, OPT_RTU, 0, 0, 0, NULL, NULL, NULL, "--rtu DEVICE", "Modbus RTU on a serial device"},
    {"baud", 0, CLI_ARG_UINT, OPT_BAUD, 0, 1200, 4000000, NULL, "expected 1200..4000000", NULL, "--baud N",
     "RTU (default 19200) or link (default 115200)"},
    {"parity", 0, CLI_ARG_WORD, OPT_PARITY, 0, 0, 0, "none|even|odd", "expected none, even or odd", NULL,
     "--parity none|even|odd", "RTU (default even), --stop-bits 1|2"},
    {"stop-bits", 0, CLI_ARG_UINT, OPT_STOP, 0, 1, 2, NULL, "expected 1 or 2", NULL, NULL, NULL},
    {"unit", 0, CLI_ARG_UINT, OPT_UNIT, 0, 0, 255, NULL, "expected 0..255", NULL, "--unit N",
     "Modbus unit id 0..255 (default 1; on TCP 0 and 255\n"
     "reach the default model)"},
    {"link", 0, CLI_ARG_TEXT, OPT_LINK, 0, 0, 0, NULL, NULL, NULL, "--link DEVICE",
     "framing protocol on a serial line or pty wired to\n"
     "one of the daemon's [link:] devices"},
    {"model", 0, CLI_ARG_UINT, OPT_MODEL, 0, 0, 254, NULL, "expected 0..254", NULL, "--model ID",
     "model id on a link, 0..254 (default 1)"},
    {"timeout", 0, CLI_ARG_UINT, OPT_TIMEOUT, 0, 10, 600000, NULL, "expected 10..600000 ms", NULL, "--timeout MS",
     "per request (default 3000)"},
    {"broker", 0, CLI_ARG_TEXT, OPT_BROKER, 0, 0, 0, NULL, NULL, NULL, "--broker HOST:PORT",
     "'it2nctl spb status|eval': through a Sparkplug B\n"
     "edge node's DCMD query on this MQTT broker (PORT\n"
     "default 1883), with --group G --node N; --model ID\n"
     "is the device model-ID (default 1)"},
    {"group", 0, CLI_ARG_TEXT, OPT_GROUP, 0, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"node", 0, CLI_ARG_TEXT, OPT_NODE, 0, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"count", 0, CLI_ARG_UINT, OPT_COUNT, O_COUNT, 1, 1000000000, NULL, "expected 1 or more", NULL, NULL, NULL},
    {"follow", 0, CLI_ARG_NONE, OPT_FOLLOW, O_FOLLOW, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"incomplete", 0, CLI_ARG_NONE, OPT_INCOMPLETE, O_INCOMPLETE, 0, 0, NULL, NULL, NULL, NULL, NULL},
};

/* The connection options are the option list of both help texts. */
static const cli_optset own_set = CLI_OPTSET(own_opts);

/* Listed with the commands; `it2nctl spb ...` has a form of its own
 * (ctl_spb_args). */
static const cli_cmd_text spb_text = {"spb", "", "Sparkplug B host mode: spb watch, spb status, spb eval", ""};

#define usage_error(...) cli_usage_error("it2nctl", __VA_ARGS__)

static int open_session(const ctl_args *a, ctl_session *s)
{
    int rc = CTL_EXIT_OK;
    if (a->conn.broker != NULL) {
        s->c = ctl_spb_open(&a->conn, &s->ops, &rc);
        snprintf(s->wbuf, sizeof(s->wbuf), "%s/%s model-%u", a->conn.group, a->conn.node, a->conn.model);
    } else if (a->conn.link != NULL) {
        s->c = ctl_link_open(&a->conn, &s->ops, &rc);
        snprintf(s->wbuf, sizeof(s->wbuf), "%s model %u", a->conn.link, a->conn.model);
    } else {
        s->c = ctl_modbus_open(&a->conn, &s->ops, &rc);
        if (a->conn.rtu != NULL) {
            snprintf(s->wbuf, sizeof(s->wbuf), "%s unit %u", a->conn.rtu, a->conn.unit);
        } else {
            snprintf(s->wbuf, sizeof(s->wbuf), "%s unit %u", a->conn.tcp ? a->conn.tcp : "127.0.0.1:1502",
                     a->conn.unit);
        }
    }
    s->where = s->wbuf;
    return s->c == NULL ? rc : CTL_EXIT_OK;
}

/* ---- options ------------------------------------------------------------ */

/* Options may come before the command (it2nctl --tcp H:P status): the
 * first word that is not an option or an option's value is moved to the
 * front, the rest keep their order. Returns -1, or an exit status. */
static int command_first(int argc, char **argv)
{
    const cli_optset sets[2] = {cli_common_opts, own_set};
    char *cmd;
    int i = 1;
    while (i < argc && argv[i][0] == '-') {
        const cli_opt *lo = NULL;
        if (argv[i][1] == '-' && strchr(argv[i], '=') == NULL) {
            lo = cli_opt_find(sets, 2, argv[i] + 2);
        }
        i += (lo != NULL && lo->arg != CLI_ARG_NONE) || strcmp(argv[i], "-o") == 0 ? 2 : 1;
    }
    if (i >= argc) {
        return usage_error(NULL, "%s",
                           "no command given (it may stand "
                           "before or after the options)");
    }
    cmd = argv[i];
    memmove(&argv[2], &argv[1], (size_t)(i - 1) * sizeof(argv[0]));
    argv[1] = cmd;
    return -1;
}

static const cli_prog prog = {
    .name = "it2nctl",
    .cmds = cmds,
    .ncmds = NCMDS,
    .stride = sizeof(cmds[0]),
    .synopsis = "COMMAND [ARGS] [OPTIONS]",
    .about = "Client for a running it2nd (Modbus TCP/RTU or a protocol link).",
    .width = 7,
    .more = &spb_text,
    .nmore = 1,
    .notes = "",
    .operands = "",
    .tail = " [CONNECTION] [--decimals N]",
    .opts_title = "Connection (default Modbus TCP 127.0.0.1:1502, unit 1):\n",
    .opts = &own_set,
    .opts_width = 20,
    .opts_tail = "Without --tcp, --rtu or --link: $IT2NCTL_TCP if set, else\n"
                 "127.0.0.1:1502.\n"
                 "Common: --decimals N (0..9, default 6), --help.\n"
                 "Exit status: 0 ok, 1 usage error, 2 data error or refused by the\n"
                 "daemon, 3 daemon unreachable or not answering.\n",
    .reorder = command_first,
};

/* --help, --version and the command word into a->cmd; -1 to go on. */
static int first_word(int argc, char **argv, ctl_args *a)
{
    int rc;
    a->cmd = cli_first_word(&prog, argc, argv, &rc);
    if (a->cmd == NULL) {
        return rc;
    }
    a->o.cmd = a->cmd->t.name;
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
    int nconn =
        cli_opt_seen(p, OPT_TCP) + cli_opt_seen(p, OPT_RTU) + cli_opt_seen(p, OPT_LINK) + cli_opt_seen(p, OPT_BROKER);
    const char *env = getenv("IT2NCTL_TCP");
    if (nconn > 1) {
        return usage_error(p->cmd, "%s", "give one of --tcp, --rtu and --link");
    }
    if (nconn == 0 && env != NULL && env[0] != '\0') {
        char host[128], port[16];
        const char *bad = ctl_tcp_split(env, host, sizeof(host), port, sizeof(port));
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
    const cli_optset sets[2] = {cli_common_opts, own_set};
    const ctl_cmd *c;
    cli_parser p;
    cli_optval v;
    char **ops;
    int id, nops, rc = first_word(argc, argv, a);
    if (rc >= 0) {
        return rc;
    }
    c = a->cmd;
    cli_opt_init(&p, "it2nctl", c->t.name, c->opts, sets, 2, argc, argv, 2);
    while ((id = cli_opt_next(&p, &v)) != CLI_OPT_END) {
        if ((rc = cli_builtin_opt(&prog, c, id)) >= 0) {
            return rc;
        }
        rc = id >= CLI_OPT_PROG ? take_own(&p, &v, a) : cli_common_take(&p, &v, &a->o);
        if (rc >= 0) {
            return rc;
        }
    }
    if ((rc = finish_conn(&p, a)) >= 0) {
        return rc;
    }
    nops = cli_opt_operands(&p, &ops);
    if ((c->opts & O_DATA) && nops != 1) {
        return usage_error(c->t.name, "%s", nops == 0 ? "missing DATA.csv" : "expected exactly one DATA.csv");
    }
    if (!(c->opts & O_DATA) && nops != 0) {
        return usage_error(c->t.name, "unexpected argument '%s'", ops[0]);
    }
    a->o.path = (c->opts & O_DATA) ? ops[0] : NULL;
    if ((c->opts & O_FOLLOW) && a->count != 0u && !a->follow) {
        return usage_error(c->t.name, "%s", "--count needs --follow");
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
    if (*argc == 3 && (strcmp((*argv)[2], "--help") == 0 || strcmp((*argv)[2], "-h") == 0)) {
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
    if (*argc < 3 || (strcmp((*argv)[2], "eval") != 0 && strcmp((*argv)[2], "status") != 0)) {
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
        return usage_error(a->cmd->t.name, "%s",
                           "--broker, --group and --node belong to "
                           "'it2nctl spb status|eval'");
    }
    if (spb && (!a->conn.broker || !a->conn.group || !a->conn.node)) {
        return usage_error(a->cmd->t.name, "%s",
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
    if (rc < 0) {
        rc = ctl_spb_check(&a, argv[0]);
    }
    if (rc >= 0) {
        free(a.o.at);
        return rc;
    }
    /* Bad data is reported before the daemon is contacted. */
    if (a.cmd->opts & O_DATA) {
        rc = ctl_load(&a.o);
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
    rc = a.cmd->run(&s, &a);
    s.ops->close(s.c);
    free(a.o.at);
    cli_free_bspline();
    return rc;
}
