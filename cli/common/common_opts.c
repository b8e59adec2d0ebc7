/* The options it2n and it2nctl share, as one table, and what they do to
 * cli_opts: both programs read --at, --grid, -o, ... with this code. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define CLI_GRID_DEFAULT 21u

static const cli_opt common[] = {
    {"kind", 0, CLI_ARG_WORD, CLI_OPT_KIND, CLI_O_KIND, 0, 0, "bezier|bspline", "expected bezier or bspline",
     "(the daemon's model has its kind)", "--kind K",
     "bezier (default: one Bezier patch, grids up to 8x8)\n"
     "or bspline (cubic not-a-knot B-spline, grids up to\n"
     "256x256; every command)"},
    {"chord", 0, CLI_ARG_NONE, CLI_OPT_CHORD, CLI_O_CHORD, 0, 0, NULL, NULL, NULL, "--chord",
     "chord-length parameters instead of uniform i/n, j/m"},
    {"decimals", 0, CLI_ARG_UINT, CLI_OPT_DECIMALS, 0, 0, 9, NULL, "expected 0..9", NULL, "--decimals N",
     "digits after the point, 0..9 (default 6)"},
    {"help", 'h', CLI_ARG_NONE, CLI_OPT_HELP, 0, 0, 0, NULL, NULL, NULL, "-h, --help", "this help"},
    {"version", 0, CLI_ARG_NONE, CLI_OPT_VERSION, 0, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"at", 0, CLI_ARG_TEXT, CLI_OPT_AT, CLI_O_AT_UW | CLI_O_AT_XY, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"summary", 0, CLI_ARG_NONE, CLI_OPT_SUMMARY, CLI_O_SUMMARY, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"grid", 0, CLI_ARG_TEXT, CLI_OPT_GRID, CLI_O_GRID | CLI_O_GRID_OPT, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"footprint", 0, CLI_ARG_TEXT, CLI_OPT_FP, CLI_O_FP, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"output", 'o', CLI_ARG_TEXT, CLI_OPT_OUTPUT, CLI_O_OUT, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"membership", 0, CLI_ARG_WORD, CLI_OPT_MEMB, CLI_O_MEMB, 0, 0, "T|I|F|all", "expected T, I, F or all", NULL, NULL,
     NULL},
    {"interval", 0, CLI_ARG_NONE, CLI_OPT_INTERVAL, CLI_O_PLOT, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"nets", 0, CLI_ARG_NONE, CLI_OPT_NETS, CLI_O_PLOT, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"size", 0, CLI_ARG_TEXT, CLI_OPT_SIZE, CLI_O_PLOT, 0, 0, NULL, NULL, NULL, NULL, NULL},
};

const cli_optset cli_common_opts = CLI_OPTSET(common);

void cli_opts_init(cli_opts *o)
{
    memset(o, 0, sizeof(*o));
    o->decimals = 6;
    o->membership = -1;
    o->format = -1;
}

/* --at: one more pair, parameters or a location by the command. */
static int take_at(const cli_parser *p, const char *text, cli_opts *o)
{
    const char *why = NULL;
    cli_at *n = realloc(o->at, (o->nat + 1u) * sizeof(*o->at));
    if (n == NULL) {
        fprintf(stderr, "%s: out of memory\n", p->prog);
        return 2;
    }
    o->at = n;
    if (cli_parse_pair(text, (p->cmdbits & CLI_O_AT_UW) != 0u, &o->at[o->nat], &why) != 0) {
        return cli_usage_error(p->prog, p->cmd, "--at '%s': %s", text, why);
    }
    o->nat++;
    return -1;
}

/* --grid RxC: plot and export hold the samples, so at most 1001 a side. */
static int take_grid(const cli_parser *p, const char *text, cli_opts *o)
{
    if (!cli_parse_grid(text, &o->rows, &o->cols)) {
        return cli_usage_error(p->prog, p->cmd,
                               "--grid '%s': expected RxC with R, C in "
                               "2..65535",
                               text);
    }
    if ((p->cmdbits & CLI_O_GRID_OPT) && (o->rows > CLI_GRID_MAX_MESH || o->cols > CLI_GRID_MAX_MESH)) {
        return cli_usage_error(p->prog, p->cmd, "--grid '%s': at most 1001x1001 here", text);
    }
    return -1;
}

int cli_common_take(const cli_parser *p, const cli_optval *v, cli_opts *o)
{
    const char *t = v->text;
    switch (v->opt->id) {
    case CLI_OPT_KIND: o->kind = v->num == 0u ? CLI_KIND_BEZIER : CLI_KIND_BSPLINE; return -1;
    case CLI_OPT_CHORD: o->flags |= IT2N_F_CHORD; return -1;
    case CLI_OPT_DECIMALS: o->decimals = (unsigned)v->num; return -1;
    case CLI_OPT_AT: return take_at(p, t, o);
    case CLI_OPT_SUMMARY: o->summary = true; return -1;
    case CLI_OPT_GRID: return take_grid(p, t, o);
    case CLI_OPT_FP:
        return cli_parse_fps(t, &o->fpmask) ? -1
                                            : cli_usage_error(p->prog, p->cmd,
                                                              "--footprint '%s': expected names from "
                                                              "LL,LR,L,D,R,RL,RR separated by commas",
                                                              t);
    case CLI_OPT_OUTPUT: o->output = t; return -1;
    case CLI_OPT_MEMB: o->membership = v->num == 3u ? -1 : (int)v->num; return -1;
    case CLI_OPT_INTERVAL: o->interval = true; return -1;
    case CLI_OPT_NETS: o->nets = true; return -1;
    case CLI_OPT_SIZE:
        return cli_parse_grid(t, &o->width, &o->height) && o->width >= 200u && o->height >= 200u && o->width <= 8000u &&
                       o->height <= 8000u
                   ? -1
                   : cli_usage_error(p->prog, p->cmd,
                                     "--size '%s': expected WxH with W, H in "
                                     "200..8000",
                                     t);
    default: return -1;
    }
}

/* plot: -o FILE.png or FILE.svg, and --interval's one membership. */
static int finish_plot(const cli_parser *p, cli_opts *o)
{
    const char *dot = o->output ? strrchr(o->output, '.') : NULL;
    if (o->output == NULL) {
        return cli_usage_error(p->prog, p->cmd, "%s needs -o FILE.png or -o FILE.svg", p->cmd);
    }
    if (dot == NULL || (strcasecmp(dot, ".png") != 0 && strcasecmp(dot, ".svg") != 0)) {
        return cli_usage_error(p->prog, p->cmd, "-o '%s': the name must end in .png or .svg", o->output);
    }
    if (o->interval && cli_opt_seen(p, CLI_OPT_MEMB) && o->membership == -1) {
        return cli_usage_error(p->prog, p->cmd,
                               "--interval needs one membership: "
                               "--membership T, I or F");
    }
    if (o->interval && o->fpmask != 0u) {
        return cli_usage_error(p->prog, p->cmd,
                               "--interval uses LL, LR, D, RL, RR: "
                               "no --footprint");
    }
    return -1;
}

int cli_common_finish(const cli_parser *p, cli_opts *o)
{
    unsigned bits = p->cmdbits;
    if ((bits & (CLI_O_AT_UW | CLI_O_AT_XY)) && o->nat == 0u) {
        return cli_usage_error(p->prog, p->cmd, "%s needs at least one --at", p->cmd);
    }
    if ((bits & CLI_O_GRID) && !cli_opt_seen(p, CLI_OPT_GRID)) {
        return cli_usage_error(p->prog, p->cmd, "%s needs --grid RxC", p->cmd);
    }
    if ((bits & CLI_O_GRID_OPT) && !cli_opt_seen(p, CLI_OPT_GRID)) {
        o->rows = o->cols = (bits & CLI_O_PLOT) && o->interval ? CLI_GRID_INTERVAL : CLI_GRID_DEFAULT;
    }
    if (bits & CLI_O_PLOT) {
        int rc = finish_plot(p, o);
        if (rc >= 0) {
            return rc;
        }
    }
    if (!cli_opt_seen(p, CLI_OPT_MEMB)) {
        o->membership = (bits & CLI_O_PLOT) && o->interval ? 0 : -1;
    }
    return -1;
}
