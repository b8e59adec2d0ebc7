/*
 * it2n host CLI: options shared between option parsing (main.c) and the
 * commands (commands.c). The CLI holds no maths: it reads CSV, calls
 * firmware_core and prints CSV.
 */
#ifndef IT2N_CLI_H
#define IT2N_CLI_H

#include "csv.h"
#include "it2n.h"
#include "opt.h"

#include <stdbool.h>
#include <stddef.h>

/* The project's version, from the file VERSION (the Makefile passes it). */
#ifndef IT2N_VERSION
#error "IT2N_VERSION undefined: build with the top-level Makefile (-DIT2N_VERSION from VERSION)"
#endif
#define IT2N_CLI_VERSION IT2N_VERSION

/* Exit statuses (documented in docs/cli.md and it2n.1). */
enum {
    CLI_EXIT_OK = 0,
    CLI_EXIT_USAGE = 1, /* bad command line                        */
    CLI_EXIT_DATA = 2   /* bad data, unreadable file, core failure */
};

/* One --at pair: parameters (u, w) in Q32 or a location (x, y) in Q24. */
typedef struct cli_at {
    int64_t a, b;
} cli_at;

typedef struct cli_opts {
    const char *cmd;     /* subcommand name                  */
    const char *path;    /* DATA.csv, "-" for stdin          */
    unsigned flags;      /* extra IT2N_F_* (CHORD)           */
    unsigned decimals;   /* 0..9 (parameters: at least 6)    */
    bool summary;        /* eval/sample: interval summary    */
    unsigned rows, cols; /* sample --grid                    */
    cli_at *at;          /* --at list (malloc'd)             */
    size_t nat;
    unsigned fpmask;        /* --footprint: bit per IT2N_FP_*, 0 = all */
    int membership;         /* plot/export: 0..2 = T,I,F; -1 = all     */
    bool interval;          /* plot --interval: band heat map   */
    const char *output;     /* plot/export -o FILE (NULL: stdout) */
    int format;             /* export --format: CLI_FMT_*       */
    unsigned width, height; /* plot --size WxH (pixels); 0: by figure */
    bool nets;              /* plot --nets: draw the control nets */
    int kind;               /* --kind: CLI_KIND_*               */
} cli_opts;

/* --kind: the paper's Bezier patch (default) or the cubic B-spline. */
enum { CLI_KIND_BEZIER = 0, CLI_KIND_BSPLINE };

/* export --format */
enum { CLI_FMT_VTK = 0, CLI_FMT_OBJ, CLI_FMT_CSV };

/* Largest --grid side for plot and export (they hold the samples). */
#define CLI_GRID_MAX_MESH 1001u
#define CLI_PAR_DECIMALS 6u /* digits of u, w whatever --decimals says */
/* plot --interval's default (x, y) nodes per side: fine enough that the
 * heat map's cells are smaller than the lines of the surfaces plot. */
#define CLI_GRID_INTERVAL 81u

/* "<stdin>" for "-", else path: how messages name DATA.csv. */
const char *cli_display_name(const char *path);

/* Read DATA.csv (o->path, "-" = stdin) with o->flags into csv and ds,
 * check it and solve it into mdl, as every it2n command does. Errors are
 * printed as FILE:LINE: ...; returns CLI_EXIT_OK or CLI_EXIT_DATA. Also
 * it2nctl's push, so both tools refuse a file alike. */
int cli_load(const cli_opts *o, cli_csv_reader *csv, it2n_dataset *ds, it2n_model *mdl);

/*
 * The options both programs share (common_opts.c), in one cli_opt table:
 * each command of either program says which apply by these bits
 * (cli_opt.cmds); a program's own bits start at CLI_O_PROG.
 */
enum {
    CLI_O_AT_UW = 0x01u,    /* --at U,W (required)                  */
    CLI_O_AT_XY = 0x02u,    /* --at X,Y (required)                  */
    CLI_O_SUMMARY = 0x04u,  /* --summary                            */
    CLI_O_GRID = 0x08u,     /* --grid required                      */
    CLI_O_GRID_OPT = 0x10u, /* --grid optional (default 21x21)      */
    CLI_O_FP = 0x20u,       /* --footprint                          */
    CLI_O_OUT = 0x40u,      /* -o FILE                              */
    CLI_O_MEMB = 0x80u,     /* --membership                         */
    CLI_O_PLOT = 0x100u,    /* --interval, --nets, --size; -o needed */
    CLI_O_CHORD = 0x200u,   /* --chord                              */
    CLI_O_KIND = 0x400u,    /* --kind                               */
    CLI_O_PROG = 0x10000u   /* first bit of a program's own          */
};

/* Ids of the shared options; a program's own ids start at CLI_OPT_PROG. */
enum {
    CLI_OPT_KIND = 0,
    CLI_OPT_CHORD,
    CLI_OPT_DECIMALS,
    CLI_OPT_HELP,
    CLI_OPT_VERSION,
    CLI_OPT_AT,
    CLI_OPT_SUMMARY,
    CLI_OPT_GRID,
    CLI_OPT_FP,
    CLI_OPT_OUTPUT,
    CLI_OPT_MEMB,
    CLI_OPT_INTERVAL,
    CLI_OPT_NETS,
    CLI_OPT_SIZE,
    CLI_OPT_PROG = 24
};

/* The shared table (its labels are it2n's "Common options" of --help). */
extern const cli_optset cli_common_opts;

/*
 * What `PROG --help` and `PROG CMD --help` say of a command: the first
 * member of every entry of a program's command table (the rest of an entry
 * is the program's own: option bits, what runs it).
 */
typedef struct cli_cmd_text {
    const char *name;
    const char *args;    /* synopsis after the command's operands     */
    const char *summary; /* one line of `PROG --help`'s command list  */
    const char *help;    /* details of `PROG CMD --help`              */
} cli_cmd_text;

/*
 * A program as cli_first_word and the help see it: its command table and
 * the words of its help, which prog.c lays out the same way for both:
 *
 *   Usage: PROG SYNOPSIS            Usage: PROG CMD OPERANDS ARGS TAIL
 *   ABOUT
 *                                   HELP
 *   Commands:
 *     NAME SUMMARY  (cmds, more)    OPTIONS
 *
 *   NOTES'PROG COMMAND --help' for details; 'PROG --version'.
 *
 *   OPTIONS
 *
 * OPTIONS: opts_title, the labelled options of opts (cli_opt_help, labels
 * padded to opts_width), opts_tail.
 */
typedef struct cli_prog {
    const char *name; /* "it2n", for messages and --version          */
    const void *cmds; /* entries of `stride` bytes, each starting    */
    size_t ncmds;     /* with its cli_cmd_text                       */
    size_t stride;
    const char *synopsis;     /* after "Usage: PROG "                  */
    const char *about;        /* one line (no '\n' at the end)         */
    int width;                /* the command names' column             */
    const cli_cmd_text *more; /* listed after the table, not in it     */
    size_t nmore;             /* (it2nctl spb: a form of its own)      */
    const char *notes;        /* lines before "'PROG COMMAND --help'"  */
    const char *operands;     /* after CMD: " DATA.csv" or ""          */
    const char *tail;         /* after ARGS: what every command takes  */
    const char *opts_title;
    const cli_optset *opts;
    unsigned opts_width;
    const char *opts_tail;
    /* Options before the command (NULL: not allowed): move the command to
     * argv[1]; -1, or an exit status after a message. */
    int (*reorder)(int argc, char **argv);
} cli_prog;

/* The command of argv[1] (help, version and a missing or unknown command,
 * with a "did you mean", handled here alike for both programs). Returns
 * its entry, or NULL with *rc the exit status when there is no more to do. */
const void *cli_first_word(const cli_prog *pg, int argc, char **argv, int *rc);

/* The answers both programs give alike to an option id after the command:
 * CLI_OPT_ERROR the usage status (cli_opt_next printed why), CLI_OPT_HELP
 * `PROG CMD --help` and 0, CLI_OPT_VERSION the --version line of
 * cli_first_word and 0. -1 for any other id: the caller's to take. */
int cli_builtin_opt(const cli_prog *pg, const void *cmd, int id);

/* Defaults of cli_opts before parsing (decimals 6, membership -1). */
void cli_opts_init(cli_opts *o);

/* Store shared option v (one of cli_common_opts, not help or version)
 * into o. Returns -1 to go on, or an exit status after its message. */
int cli_common_take(const cli_parser *p, const cli_optval *v, cli_opts *o);

/* After the last option: what the command's bits require of the shared
 * options (--at, --grid, -o FILE.png|svg, --interval's limits) and the
 * defaults that depend on others (grid size, membership). -1 or a status. */
int cli_common_finish(const cli_parser *p, cli_opts *o);

/* Option values (cli/common/args.c). cli_parse_pair: "A,B", both parameters in
 * [0,1] (par) or both values; 0, or an error with *why set. cli_parse_grid:
 * "RxC", R and C in 2..65535. cli_parse_fps: "D", "LL,RR", ... or'ed into
 * *mask as bits of IT2N_FP_*. */
int cli_parse_pair(const char *s, bool par, cli_at *out, const char **why);
bool cli_parse_grid(const char *s, unsigned *r, unsigned *c);
bool cli_parse_fps(const char *s, unsigned *mask);

/*
 * A data set of either kind as DATA.csv was read, read through one set of
 * accessors (what it2nctl push uploads over any transport, the data points
 * plot draws): at most one of ds (Bezier) and bds (B-spline) is set; n, m
 * (grid i in 0..n, j in 0..m) and flags (IT2N_F_*) are copied from it.
 * Neither set: no data (n = m = 0, no entry present).
 */
typedef struct cli_data {
    const it2n_dataset *ds;
    const it2n_bspline_data *bds;
    unsigned n, m, flags;
} cli_data;

/* The data of a Bezier (ds) or a B-spline (bds) data set; NULL: none. */
cli_data cli_data_bezier(const it2n_dataset *ds);
cli_data cli_data_bspline(const it2n_bspline_data *bds);

/* True if entry (i, j, fp) is present (a type-1 set holds D only); false
 * outside the grid. */
bool cli_data_has(const cli_data *d, unsigned i, unsigned j, unsigned fp);

/* Present entry (i, j, fp) with memberships in Q24 (cli_data_get) or as
 * stored, in Q30 (cli_data_get_fine). */
void cli_data_get(const cli_data *d, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT]);
void cli_data_get_fine(const cli_data *d, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT]);

/* How many entries are present: what a push uploads. */
unsigned cli_data_count(const cli_data *d);

/*
 * A solved model of either kind, for plot and export (and it2nctl's live
 * drawing): exactly one of bez, bsp is set. The data points are drawn from
 * data where it has them (it2n), else from the surface at the parameter
 * nodes, where it interpolates them (it2nctl: no data; uniform parameters
 * only).
 */
typedef struct cli_surface {
    const it2n_model *bez;
    const it2n_bspline_model *bsp;
    cli_data data; /* of the model's kind, or none */
} cli_surface;

unsigned cli_surf_n(const cli_surface *s); /* intervals (Bezier: degree) */
unsigned cli_surf_m(const cli_surface *s);
unsigned cli_surf_flags(const cli_surface *s);
bool cli_surf_has_fp(const cli_surface *s, unsigned fp);
int cli_surf_eval(const cli_surface *s, it2n_par u, it2n_par w, it2n_point *pt, it2n_errinfo *err);
int cli_surf_locate(const cli_surface *s, it2n_val x, it2n_val y, it2n_locate_result *out, it2n_errinfo *err);
int cli_surf_sample(const cli_surface *s, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx,
                    it2n_errinfo *err);
/* The net drawn by --nets: Bezier control points ((n+1) x (m+1)) or the
 * B-spline coefficients ((n+3) x (m+3)), as coefficient (r, c) in Q24. */
unsigned cli_surf_net_rows(const cli_surface *s);
unsigned cli_surf_net_cols(const cli_surface *s);
it2n_val cli_surf_coef(const cli_surface *s, unsigned r, unsigned c, unsigned fp, unsigned ch);
/* Data point (i, j) of footprint fp into v: true if the data set has it. */
bool cli_surf_point(const cli_surface *s, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT]);

/* True if footprint fp is selected by --footprint (and in the model). */
bool cli_fp_selected(const cli_opts *o, const cli_surface *mdl, unsigned fp);

/* Exact decimal text of a Q24 value into buf (at least 48 bytes). */
void cli_fmt_val(char *buf, size_t size, it2n_val v, unsigned decimals);

/*
 * Samples of every footprint surface on an R x C grid, held in memory for
 * plot and export: v[((r * cols + c) * IT2N_FP_COUNT + fp) * IT2N_CH_COUNT
 * + ch], u[r], w[c].
 */
typedef struct cli_mesh {
    unsigned rows, cols;
    it2n_val *v;
    it2n_par *u, *w;
} cli_mesh;

/* Fill mesh from it2n_sample; returns an exit status (message printed). */
int cli_mesh_sample(cli_mesh *mesh, const cli_surface *mdl, unsigned rows, unsigned cols);
void cli_mesh_free(cli_mesh *mesh);

static inline it2n_val cli_mesh_at(const cli_mesh *m, unsigned r, unsigned c, unsigned fp, unsigned ch)
{
    return m->v[(((size_t)r * m->cols + c) * IT2N_FP_COUNT + fp) * IT2N_CH_COUNT + ch];
}

/* it2n plot and it2n export (plot.c, export.c); the model is solved. */
int cli_plot(const cli_opts *o, const cli_surface *mdl);
int cli_export(const cli_opts *o, const cli_surface *mdl);

/* The B-spline reader of it2n --kind bspline for it2nctl push: reads and
 * solves o->path into heap storage (freed by cli_free_bspline); *bds,
 * *bmdl and *csv (line numbers for messages) stay valid until then.
 * Errors printed as FILE:LINE: ...; CLI_EXIT_OK or CLI_EXIT_DATA. */
int cli_load_bspline(const cli_opts *o, const it2n_bspline_data **bds, const it2n_bspline_model **bmdl,
                     const cli_csv_reader **csv);
void cli_free_bspline(void);

#endif /* IT2N_CLI_H */
