/*
 * it2n — host command-line tool for IT2NBS interpolation models.
 * Option parsing and help texts; the commands are in commands.c.
 * Exit status: 0 ok, 1 usage error, 2 data error.
 */
#include "cli.h"

#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

typedef struct cli_cmd {
    const char *name;
    const char *args;     /* synopsis after DATA.csv         */
    const char *summary;  /* one line for `it2n --help`      */
    const char *help;     /* details for `it2n CMD --help`   */
    unsigned opts;        /* CLI_O_* accepted                */
} cli_cmd;

#define CLI_O_AT_UW 0x01u
#define CLI_O_AT_XY 0x02u
#define CLI_O_SUMMARY 0x04u
#define CLI_O_GRID 0x08u     /* --grid required                  */
#define CLI_O_GRID_OPT 0x10u /* --grid optional (default 21x21)  */
#define CLI_O_FP 0x20u       /* --footprint                      */
#define CLI_O_OUT 0x40u      /* -o FILE                          */
#define CLI_O_MEMB 0x80u     /* --membership                     */
#define CLI_O_PLOT 0x100u    /* --interval, --size               */
#define CLI_O_FORMAT 0x200u  /* --format                         */

#define CLI_MEMB_UNSET (-2)
#define CLI_GRID_DEFAULT 21u

static const char common_help[] =
    "Common options:\n"
    "  --kind K        bezier (default: one Bezier patch, grids up to 8x8)\n"
    "                  or bspline (cubic not-a-knot B-spline, grids up to\n"
    "                  256x256; every command)\n"
    "  --chord         chord-length parameters instead of uniform i/n, j/m\n"
    "  --decimals N    digits after the point, 0..9 (default 6)\n"
    "  -h, --help      this help\n"
    "DATA.csv is '-' for standard input. Exit status: 0 ok, 1 usage error,\n"
    "2 data error (message on stderr as FILE:LINE: ...).\n";

static const cli_cmd cmds[] = {
    {"check", "", "validate the dataset (and that it solves)",
     "Validate DATA.csv: header, every (i,j,footprint) exactly once,\n"
     "T,I,F in [0,1], coordinates within range, footprints nested\n"
     "LL<=LR<=L<=D<=R<=RL<=RR on every axis, and that the model solves.\n"
     "Prints one summary line on success.\n",
     0u},
    {"solve", "", "print the control nets",
     "Print the Bezier control points of every footprint surface as CSV\n"
     "with the input's columns: i,j,footprint,x,y[,z],T,I,F.\n",
     0u},
    {"eval", "--at U,W [--at U,W ...] [--summary]",
     "evaluate the surfaces at parameters (u,w)",
     "Evaluate every footprint surface at each (u,w) in [0,1]^2.\n"
     "Header u,w,footprint,x,y[,z],T,I,F,out_of_range; out_of_range names\n"
     "the memberships outside [0,1] (e.g. T|F) or is '-'.\n"
     "  --at U,W     parameters, repeatable, in order of output\n"
     "  --summary    after each point, rows upper_min, upper_max (over\n"
     "               LL,D,RR) and lower_min, lower_max (over LR,D,RL) with\n"
     "               empty coordinates and the T,I,F bounds\n",
     CLI_O_AT_UW | CLI_O_SUMMARY},
    {"sample", "--grid RxC [--summary] [--footprint FP[,FP...]]",
     "evaluate on a uniform RxC parameter grid",
     "Like eval on u = r/(R-1), w = c/(C-1), row-major; R, C in 2..65535.\n"
     "  --grid RxC        grid size\n"
     "  --summary         interval summary rows as in eval (always over all\n"
     "                    footprints)\n"
     "  --footprint LIST  only these footprints (LL,LR,L,D,R,RL,RR; comma-\n"
     "                    separated, repeatable; default all)\n",
     CLI_O_GRID | CLI_O_SUMMARY | CLI_O_FP},
    {"locate", "--at X,Y [--at X,Y ...]",
     "find each footprint's (u,w) through a location (x,y)",
     "For each footprint find (u,w) whose surface passes through (x,y) and\n"
     "print the memberships there. Header x,y,footprint,u,w[,z],T,I,F,status\n"
     "with status inside, outside (nearest boundary point) or noconv.\n"
     "  --at X,Y     location, repeatable\n",
     CLI_O_AT_XY},
    {"deriv", "--at U,W [--at U,W ...]",
     "partial derivatives dS/du and dS/dw",
     "Print dS/du (wrt=u) and dS/dw (wrt=w) of every surface at each (u,w).\n"
     "Header u,w,footprint,wrt,x,y[,z],T,I,F.\n"
     "  --at U,W     parameters, repeatable\n",
     CLI_O_AT_UW},
    {"plot",
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
     "IT2N_GNUPLOT environment variable.\n",
     CLI_O_GRID_OPT | CLI_O_FP | CLI_O_OUT | CLI_O_MEMB | CLI_O_PLOT},
    {"export",
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
     "  --footprint LIST    only these footprints (default all)\n",
     CLI_O_GRID_OPT | CLI_O_FP | CLI_O_OUT | CLI_O_MEMB | CLI_O_FORMAT},
};
#define NCMDS (sizeof(cmds) / sizeof(cmds[0]))

static void usage_all(FILE *out)
{
    size_t k;
    fprintf(out,
            "Usage: it2n COMMAND DATA.csv [OPTIONS]\n"
            "Interval type-2 neutrosophic Bezier surface interpolation.\n\n"
            "Commands:\n");
    for (k = 0; k < NCMDS; k++) {
        fprintf(out, "  %-8s %s\n", cmds[k].name, cmds[k].summary);
    }
    fprintf(out,
            "\nDATA.csv: header i,j,footprint,x,y[,z],T,I,F then one row per\n"
            "grid point and footprint (LL,LR,L,D,R,RL,RR, or D only).\n"
            "'it2n COMMAND --help' for details; 'it2n --version'.\n\n%s",
            common_help);
}

static void usage_cmd(const cli_cmd *c)
{
    printf("Usage: it2n %s DATA.csv%s%s [--kind K] [--chord] [--decimals N]\n\n%s\n%s",
           c->name, c->args[0] ? " " : "", c->args, c->help, common_help);
}

static int usage_error(const char *cmd, const char *fmt, const char *arg)
{
    fprintf(stderr, "it2n: ");
    fprintf(stderr, fmt, arg);
    fprintf(stderr, "\nTry 'it2n %s%s--help'.\n", cmd ? cmd : "",
            cmd ? " " : "");
    return CLI_EXIT_USAGE;
}

static const cli_cmd *find_cmd(const char *name)
{
    size_t k;
    for (k = 0; k < NCMDS; k++) {
        if (strcmp(cmds[k].name, name) == 0) {
            return &cmds[k];
        }
    }
    return NULL;
}

int main(int argc, char **argv)
{
    static const struct option longopts[] = {
        {"at", required_argument, NULL, 'a'},
        {"summary", no_argument, NULL, 's'},
        {"grid", required_argument, NULL, 'g'},
        {"chord", no_argument, NULL, 'c'},
        {"decimals", required_argument, NULL, 'd'},
        {"help", no_argument, NULL, 'h'},
        {"version", no_argument, NULL, 'V'},
        {"footprint", required_argument, NULL, 'f'},
        {"output", required_argument, NULL, 'o'},
        {"membership", required_argument, NULL, 'm'},
        {"interval", no_argument, NULL, 'i'},
        {"format", required_argument, NULL, 'F'},
        {"size", required_argument, NULL, 'S'},
        {"nets", no_argument, NULL, 'N'},
        {"kind", required_argument, NULL, 'K'},
        {NULL, 0, NULL, 0}};
    cli_opts o;
    const cli_cmd *c;
    bool grid = false, fmt = false;
    int opt, rc;

    memset(&o, 0, sizeof(o));
    o.decimals = 6;
    o.membership = CLI_MEMB_UNSET;
    o.format = -1;
    if (argc < 2) {
        usage_all(stderr);
        return CLI_EXIT_USAGE;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 ||
        strcmp(argv[1], "help") == 0) {
        if (argc > 2 && (c = find_cmd(argv[2])) != NULL) {
            usage_cmd(c);
        } else {
            usage_all(stdout);
        }
        return CLI_EXIT_OK;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("it2n %s (IT2N_MAX_DEGREE %d)\n", IT2N_CLI_VERSION,
               IT2N_MAX_DEGREE);
        return CLI_EXIT_OK;
    }
    c = find_cmd(argv[1]);
    if (c == NULL) {
        return usage_error(NULL, "unknown command '%s'", argv[1]);
    }
    o.cmd = c->name;

    /* getopt_long permutes, so options may come before or after DATA. */
    optind = 2;
    opterr = 0;
    while ((opt = getopt_long(argc, argv, ":ho:", longopts, NULL)) != -1) {
        const char *why = NULL;
        char *end;
        unsigned long d;
        switch (opt) {
        case 'h':
            usage_cmd(c);
            free(o.at);
            return CLI_EXIT_OK;
        case 'V':
            printf("it2n %s\n", IT2N_CLI_VERSION);
            free(o.at);
            return CLI_EXIT_OK;
        case 'c':
            o.flags |= IT2N_F_CHORD;
            break;
        case 'K':
            if (strcmp(optarg, "bezier") == 0) {
                o.kind = CLI_KIND_BEZIER;
            } else if (strcmp(optarg, "bspline") == 0) {
                o.kind = CLI_KIND_BSPLINE;
            } else {
                free(o.at);
                return usage_error(c->name,
                                   "--kind '%s': expected bezier or bspline",
                                   optarg);
            }
            break;
        case 'd':
            d = strtoul(optarg, &end, 10);
            if (*optarg < '0' || *optarg > '9' || *end != '\0' || d > 9) {
                free(o.at);
                return usage_error(c->name, "--decimals '%s': expected 0..9",
                                   optarg);
            }
            o.decimals = (unsigned)d;
            break;
        case 's':
            if (!(c->opts & CLI_O_SUMMARY)) {
                free(o.at);
                return usage_error(c->name, "--summary does not apply to %s",
                                   c->name);
            }
            o.summary = true;
            break;
        case 'f':
            if (!(c->opts & CLI_O_FP)) {
                free(o.at);
                return usage_error(c->name, "--footprint does not apply to %s",
                                   c->name);
            }
            if (!cli_parse_fps(optarg, &o.fpmask)) {
                free(o.at);
                return usage_error(c->name,
                                   "--footprint '%s': expected names from "
                                   "LL,LR,L,D,R,RL,RR separated by commas",
                                   optarg);
            }
            break;
        case 'o':
            if (!(c->opts & CLI_O_OUT)) {
                free(o.at);
                return usage_error(c->name, "-o does not apply to %s",
                                   c->name);
            }
            o.output = optarg;
            break;
        case 'm':
            if (!(c->opts & CLI_O_MEMB)) {
                free(o.at);
                return usage_error(c->name,
                                   "--membership does not apply to %s",
                                   c->name);
            }
            if (strcmp(optarg, "T") == 0) {
                o.membership = 0;
            } else if (strcmp(optarg, "I") == 0) {
                o.membership = 1;
            } else if (strcmp(optarg, "F") == 0) {
                o.membership = 2;
            } else if (strcmp(optarg, "all") == 0) {
                o.membership = -1;
            } else {
                free(o.at);
                return usage_error(c->name,
                                   "--membership '%s': expected T, I, F or all",
                                   optarg);
            }
            break;
        case 'i':
            if (!(c->opts & CLI_O_PLOT)) {
                free(o.at);
                return usage_error(c->name, "--interval does not apply to %s",
                                   c->name);
            }
            o.interval = true;
            break;
        case 'N':
            if (!(c->opts & CLI_O_PLOT)) {
                free(o.at);
                return usage_error(c->name, "--nets does not apply to %s",
                                   c->name);
            }
            o.nets = true;
            break;
        case 'S':
            if (!(c->opts & CLI_O_PLOT)) {
                free(o.at);
                return usage_error(c->name, "--size does not apply to %s",
                                   c->name);
            }
            if (!cli_parse_grid(optarg, &o.width, &o.height) || o.width < 200u ||
                o.height < 200u || o.width > 8000u || o.height > 8000u) {
                free(o.at);
                return usage_error(c->name,
                                   "--size '%s': expected WxH with W, H in "
                                   "200..8000",
                                   optarg);
            }
            break;
        case 'F':
            if (!(c->opts & CLI_O_FORMAT)) {
                free(o.at);
                return usage_error(c->name, "--format does not apply to %s",
                                   c->name);
            }
            if (strcmp(optarg, "vtk") == 0) {
                o.format = CLI_FMT_VTK;
            } else if (strcmp(optarg, "obj") == 0) {
                o.format = CLI_FMT_OBJ;
            } else if (strcmp(optarg, "csv") == 0) {
                o.format = CLI_FMT_CSV;
            } else {
                free(o.at);
                return usage_error(c->name,
                                   "--format '%s': expected vtk, obj or csv",
                                   optarg);
            }
            fmt = true;
            break;
        case 'g':
            if (!(c->opts & (CLI_O_GRID | CLI_O_GRID_OPT))) {
                free(o.at);
                return usage_error(c->name, "--grid does not apply to %s",
                                   c->name);
            }
            if (!cli_parse_grid(optarg, &o.rows, &o.cols)) {
                free(o.at);
                return usage_error(c->name,
                                   "--grid '%s': expected RxC with R, C in "
                                   "2..65535",
                                   optarg);
            }
            if ((c->opts & CLI_O_GRID_OPT) && (o.rows > CLI_GRID_MAX_MESH ||
                                               o.cols > CLI_GRID_MAX_MESH)) {
                free(o.at);
                return usage_error(c->name,
                                   "--grid '%s': at most 1001x1001 here",
                                   optarg);
            }
            grid = true;
            break;
        case 'a': {
            cli_at *n;
            if (!(c->opts & (CLI_O_AT_UW | CLI_O_AT_XY))) {
                free(o.at);
                return usage_error(c->name, "--at does not apply to %s",
                                   c->name);
            }
            n = realloc(o.at, (o.nat + 1u) * sizeof(*o.at));
            if (n == NULL) {
                free(o.at);
                fprintf(stderr, "it2n: out of memory\n");
                return CLI_EXIT_DATA;
            }
            o.at = n;
            if (cli_parse_pair(optarg, (c->opts & CLI_O_AT_UW) != 0u,
                           &o.at[o.nat], &why) != 0) {
                fprintf(stderr, "it2n: --at '%s': %s\n", optarg, why);
                fprintf(stderr, "Try 'it2n %s --help'.\n", c->name);
                free(o.at);
                return CLI_EXIT_USAGE;
            }
            o.nat++;
            break;
        }
        case ':':
            free(o.at);
            return usage_error(c->name, "option '%s' needs an argument",
                               argv[optind - 1]);
        default:
            free(o.at);
            return usage_error(c->name, "unknown option '%s'",
                               argv[optind - 1]);
        }
    }
    if (optind != argc - 1) {
        free(o.at);
        return usage_error(c->name, "%s", optind >= argc
                                              ? "missing DATA.csv"
                                              : "expected exactly one DATA.csv");
    }
    o.path = argv[optind];
    if (o.kind == CLI_KIND_BSPLINE && (o.flags & IT2N_F_CHORD)) {
        free(o.at);
        return usage_error(c->name, "%s",
                           "--chord: the B-spline kind has uniform "
                           "parameters only");
    }
    if ((c->opts & (CLI_O_AT_UW | CLI_O_AT_XY)) && o.nat == 0u) {
        free(o.at);
        return usage_error(c->name, "%s needs at least one --at", c->name);
    }
    if ((c->opts & CLI_O_GRID) && !grid) {
        free(o.at);
        return usage_error(c->name, "%s needs --grid RxC", c->name);
    }
    if ((c->opts & CLI_O_GRID_OPT) && !grid) {
        o.rows = o.cols = (c->opts & CLI_O_PLOT) && o.interval
                              ? CLI_GRID_INTERVAL
                              : CLI_GRID_DEFAULT;
    }
    if ((c->opts & CLI_O_FORMAT) && !fmt) {
        free(o.at);
        return usage_error(c->name, "%s needs --format vtk|obj|csv", c->name);
    }
    if (c->opts & CLI_O_PLOT) {
        const char *dot = o.output ? strrchr(o.output, '.') : NULL;
        if (o.output == NULL) {
            free(o.at);
            return usage_error(c->name, "%s needs -o FILE.png or -o FILE.svg",
                               c->name);
        }
        if (dot == NULL || (strcasecmp(dot, ".png") != 0 &&
                            strcasecmp(dot, ".svg") != 0)) {
            free(o.at);
            return usage_error(c->name,
                               "-o '%s': the name must end in .png or .svg",
                               o.output);
        }
        if (o.interval && o.membership == -1) {
            free(o.at);
            return usage_error(c->name, "%s",
                               "--interval needs one membership: "
                               "--membership T, I or F");
        }
        if (o.interval && o.fpmask != 0u) {
            free(o.at);
            return usage_error(c->name, "%s",
                               "--interval uses LL, LR, D, RL, RR: "
                               "no --footprint");
        }
        if (o.membership == CLI_MEMB_UNSET) {
            o.membership = o.interval ? 0 : -1;
        }
    }
    if (o.membership == CLI_MEMB_UNSET) {
        o.membership = -1;
    }
    rc = cli_run(&o);
    free(o.at);
    return rc;
}
