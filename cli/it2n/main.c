/*
 * it2n — host command-line tool for IT2NBS interpolation models.
 * Option parsing and help texts; the commands are in commands.c.
 * Exit status: 0 ok, 1 usage error, 2 data error.
 */
#include "commands.h"

#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct cli_cmd {
    cli_cmd_text t; /* name, synopsis after DATA.csv, help texts */
    unsigned opts;  /* CLI_O_* and O_* accepted                  */
} cli_cmd;

/* it2n's own option bits and ids (the shared ones: cli.h). */
#define O_FORMAT CLI_O_PROG              /* --format (export) */
#define O_ALL (CLI_O_CHORD | CLI_O_KIND) /* every command */
enum { OPT_FORMAT = CLI_OPT_PROG };

static const cli_opt own_opts[] = {
    {"format", 0, CLI_ARG_WORD, OPT_FORMAT, O_FORMAT, 0, 0, "vtk|obj|csv", "expected vtk, obj or csv", NULL, NULL,
     NULL},
};

static const cli_cmd cmds[] = {
    {{"check", "", "validate the dataset (and that it solves)",
      "Validate DATA.csv: header, every (i,j,footprint) exactly once,\n"
      "T,I,F in [0,1], coordinates within range, footprints nested\n"
      "LL<=LR<=L<=D<=R<=RL<=RR on every axis, and that the model solves.\n"
      "Prints one summary line on success.\n"},
     O_ALL},
    {{"solve", "", "print the control nets",
      "Print the Bezier control points of every footprint surface as CSV\n"
      "with the input's columns: i,j,footprint,x,y[,z],T,I,F.\n"},
     O_ALL},
    {{"eval", "--at U,W [--at U,W ...] [--summary]", "evaluate the surfaces at parameters (u,w)",
      "Evaluate every footprint surface at each (u,w) in [0,1]^2.\n"
      "Header u,w,footprint,x,y[,z],T,I,F,out_of_range; out_of_range names\n"
      "the memberships outside [0,1] (e.g. T|F) or is '-'.\n"
      "  --at U,W     parameters, repeatable, in order of output\n"
      "  --summary    after each point, rows upper_min, upper_max (over\n"
      "               LL,D,RR) and lower_min, lower_max (over LR,D,RL) with\n"
      "               empty coordinates and the T,I,F bounds\n"},
     O_ALL | CLI_O_AT_UW | CLI_O_SUMMARY},
    {{"sample", "--grid RxC [--summary] [--footprint FP[,FP...]]", "evaluate on a uniform RxC parameter grid",
      "Like eval on u = r/(R-1), w = c/(C-1), row-major; R, C in 2..65535.\n"
      "  --grid RxC        grid size\n"
      "  --summary         interval summary rows as in eval (always over all\n"
      "                    footprints)\n"
      "  --footprint LIST  only these footprints (LL,LR,L,D,R,RL,RR; comma-\n"
      "                    separated, repeatable; default all)\n"},
     O_ALL | CLI_O_GRID | CLI_O_SUMMARY | CLI_O_FP},
    {{"locate", "--at X,Y [--at X,Y ...]", "find each footprint's (u,w) through a location (x,y)",
      "For each footprint find (u,w) whose surface passes through (x,y) and\n"
      "print the memberships there. Header x,y,footprint,u,w[,z],T,I,F,status\n"
      "with status inside, outside (nearest boundary point) or noconv.\n"
      "  --at X,Y     location, repeatable\n"},
     O_ALL | CLI_O_AT_XY},
    {{"deriv", "--at U,W [--at U,W ...]", "partial derivatives dS/du and dS/dw",
      "Print dS/du (wrt=u) and dS/dw (wrt=w) of every surface at each (u,w).\n"
      "Header u,w,footprint,wrt,x,y[,z],T,I,F.\n"
      "  --at U,W     parameters, repeatable\n"},
     O_ALL | CLI_O_AT_UW},
    {{"plot",
      "-o FILE.png|FILE.svg [--membership T|I|F|all] [--interval]\n"
      "       [--nets] [--grid RxC] [--footprint LIST] [--size WxH]",
      "draw the surfaces with gnuplot",
      "Render every footprint surface (x, y, membership) with hidden lines\n"
      "removed and the data points marked, through gnuplot (PNG with pngcairo\n"
      "or SVG, from the file name). Truth is green, indeterminacy blue,\n"
      "falsity red; upper footprints (LL, RR) solid, lower (LR, RL) dashed,\n"
      "inner (L, R) dotted, the mean D thick; the z axis spans the surfaces\n"
      "and data points.\n"
      "  -o, --output FILE   FILE.png or FILE.svg (required)\n"
      "  --membership M      T, I, F or all (three panels; default)\n"
      "  --nets              also draw the control nets (points joined by thin\n"
      "                      lines; the z axis then spans them too)\n"
      "  --interval          heat maps over (x,y) of the upper band (max-min\n"
      "                      of M over LL,D,RR) and lower band (LR,D,RL), each\n"
      "                      footprint located through (x,y); M is T, I or F\n"
      "                      (default T); needs a type-2 model\n"
      "  --grid RxC          samples per surface, or (x,y) cells of the heat\n"
      "                      map; 2..1001 each (default 21x21; --interval\n"
      "                      81x81 over the region the bands cover)\n"
      "  --footprint LIST    only these footprints (default all)\n"
      "  --size WxH          image size in pixels, 200..8000 (default 900x700;\n"
      "                      all: 1500x600; --interval: 1000x500)\n"
      "gnuplot must be on PATH (Debian: gnuplot-nox), or named by the\n"
      "IT2N_GNUPLOT environment variable.\n"},
     O_ALL | CLI_O_GRID_OPT | CLI_O_FP | CLI_O_OUT | CLI_O_MEMB | CLI_O_PLOT},
    {{"export",
      "--format vtk|obj|csv [-o FILE] [--grid RxC] [--membership T|I|F|all]\n"
      "       [--footprint LIST]",
      "write the sampled surfaces as meshes (VTK, OBJ, CSV)",
      "Sample every footprint surface on an RxC grid and write one mesh per\n"
      "footprint and membership, vertices (x, y, membership), quads between\n"
      "neighbouring samples, objects in footprint order then T, I, F.\n"
      "  --format vtk   VTK legacy ASCII POLYDATA (ParaView): point data\n"
      "                 membership, u, w[, z]; cell data footprint (0..6 =\n"
      "                 LL..RR) and membership (0..2 = T,I,F)\n"
      "  --format obj   Wavefront OBJ (MeshLab): 'o FP_M' and 'g FP_M' per\n"
      "                 object, e.g. o D_T\n"
      "  --format csv   one row per vertex: object,footprint,membership,r,c,\n"
      "                 u,w,x,y[,z],value\n"
      "  -o, --output FILE   write to FILE (default standard output)\n"
      "  --grid RxC          2..1001 each (default 21x21)\n"
      "  --membership M      T, I, F or all (default all)\n"
      "  --footprint LIST    only these footprints (default all)\n"},
     O_ALL | CLI_O_GRID_OPT | CLI_O_FP | CLI_O_OUT | CLI_O_MEMB | O_FORMAT},
};
#define NCMDS (sizeof(cmds) / sizeof(cmds[0]))

static const cli_prog prog = {
    .name = "it2n",
    .cmds = cmds,
    .ncmds = NCMDS,
    .stride = sizeof(cmds[0]),
    .synopsis = "COMMAND DATA.csv [OPTIONS]",
    .about = "Interval type-2 neutrosophic Bezier surface interpolation.",
    .width = 8,
    .notes = "DATA.csv: header i,j,footprint,x,y[,z],T,I,F then one row per\n"
             "grid point and footprint (LL,LR,L,D,R,RL,RR, or D only).\n",
    .operands = " DATA.csv",
    .tail = " [--kind K] [--chord] [--decimals N]",
    .opts_title = "Common options:\n",
    .opts = &cli_common_opts,
    .opts_width = 16,
    .opts_tail = "DATA.csv is '-' for standard input. Exit status: 0 ok, 1 usage error,\n"
                 "2 data error (message on stderr as FILE:LINE: ...).\n",
};

/* The options and DATA.csv of command c into o; -1 to go on, else the
 * exit status (help printed, or a usage error). */
static int parse_cmd(const cli_cmd *c, int argc, char **argv, cli_opts *o)
{
    const cli_optset sets[2] = {cli_common_opts, CLI_OPTSET(own_opts)};
    cli_parser p;
    cli_optval v;
    char **ops;
    int id, nops, rc;

    cli_opt_init(&p, "it2n", c->t.name, c->opts, sets, 2, argc, argv, 2);
    while ((id = cli_opt_next(&p, &v)) != CLI_OPT_END) {
        if ((rc = cli_builtin_opt(&prog, c, id)) >= 0) {
            return rc;
        } else if (id == OPT_FORMAT) {
            o->format = (int)v.num; /* CLI_FMT_* in the order of words */
        } else if ((rc = cli_common_take(&p, &v, o)) >= 0) {
            return rc;
        }
    }
    nops = cli_opt_operands(&p, &ops);
    if (nops != 1) {
        return cli_usage_error("it2n", c->t.name, "%s",
                               nops == 0 ? "missing DATA.csv" : "expected exactly one DATA.csv");
    }
    o->path = ops[0];
    if (o->kind == CLI_KIND_BSPLINE && (o->flags & IT2N_F_CHORD)) {
        return cli_usage_error("it2n", c->t.name, "%s", "--chord: the B-spline kind has uniform parameters only");
    }
    if ((c->opts & O_FORMAT) && !cli_opt_seen(&p, OPT_FORMAT)) {
        return cli_usage_error("it2n", c->t.name, "%s needs --format vtk|obj|csv", c->t.name);
    }
    return cli_common_finish(&p, o);
}

int main(int argc, char **argv)
{
    cli_opts o;
    int rc;
    const cli_cmd *c = cli_first_word(&prog, argc, argv, &rc);
    if (c == NULL) {
        return rc;
    }
    cli_opts_init(&o);
    o.cmd = c->t.name;
    rc = parse_cmd(c, argc, argv, &o);
    if (rc < 0) {
        rc = cmd_run(&o);
    }
    free(o.at);
    return rc;
}
