/*
 * cmocka tests of the front ends' option parser (cli/common/opt.c) and the
 * shared options' table (cli/common/common_opts.c): argv scanning, values
 * checked against the table, options of other commands refused, "did you
 * mean", the usage messages word for word, the help lists.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "cli.h"

/* Messages are checked as written: stderr (or stdout) into memory. */
static char *g_buf;
static size_t g_len;
static FILE *g_saved;

static void capture(FILE **which)
{
    g_saved = *which;
    *which = open_memstream(&g_buf, &g_len);
    assert_non_null(*which);
}

/* The captured text (caller frees). */
static char *release(FILE **which)
{
    fclose(*which);
    *which = g_saved;
    return g_buf;
}

enum { T_FLAG = 0, T_NUM, T_WORD, T_TEXT, T_ONLY };
#define C_A 1u
#define C_B 2u

static const cli_opt tab[] = {
    {"flag", 'f', CLI_ARG_NONE, T_FLAG, 0, 0, 0, NULL, NULL, NULL, "-f, --flag",
     "a flag"},
    {"num", 0, CLI_ARG_UINT, T_NUM, 0, 2, 40, NULL, "expected 2..40", NULL,
     "--num N", "a number\nover two lines"},
    {"word", 0, CLI_ARG_WORD, T_WORD, 0, 0, 0, "red|green|blue",
     "expected red, green or blue", NULL, "--word-with-a-long-label W",
     "a colour"},
    {"text", 'o', CLI_ARG_TEXT, T_TEXT, 0, 0, 0, NULL, NULL, NULL, NULL, NULL},
    {"only-b", 0, CLI_ARG_NONE, T_ONLY, C_B, 0, 0, NULL, NULL, "(B's own)",
     "--only-b", "for B"},
};

/* Parse words (NULL-terminated, after "prog cmd") for command bits. */
static int parse(unsigned bits, char **argv, int argc, cli_parser *p,
                 cli_optval *vals, int *nvals)
{
    const cli_optset sets[1] = {CLI_OPTSET(tab)};
    int id;
    *nvals = 0;
    cli_opt_init(p, "prog", "cmd", bits, sets, 1, argc, argv, 2);
    while ((id = cli_opt_next(p, &vals[*nvals])) >= 0) {
        (*nvals)++;
    }
    return id;
}

static void test_scan_values_and_operands(void **state)
{
    char *argv[] = {"prog", "cmd", "in.csv", "--num", "7", "-f",
                    "--word=blue", "-oout.png", "second", "--", "--flag",
                    "-", NULL};
    cli_parser p;
    cli_optval v[8];
    char **ops;
    int n;
    (void)state;
    assert_int_equal(parse(C_A, argv, 12, &p, v, &n), CLI_OPT_END);
    assert_int_equal(n, 4);
    assert_int_equal(v[0].opt->id, T_NUM);
    assert_int_equal(v[0].num, 7);
    assert_int_equal(v[1].opt->id, T_FLAG);
    assert_int_equal(v[2].opt->id, T_WORD);
    assert_int_equal(v[2].num, 2); /* blue */
    assert_int_equal(v[3].opt->id, T_TEXT);
    assert_string_equal(v[3].text, "out.png");
    assert_true(cli_opt_seen(&p, T_NUM));
    assert_false(cli_opt_seen(&p, T_ONLY));
    /* operands in order; after "--" an option-like word is one too */
    assert_int_equal(cli_opt_operands(&p, &ops), 4);
    assert_string_equal(ops[0], "in.csv");
    assert_string_equal(ops[1], "second");
    assert_string_equal(ops[2], "--flag");
    assert_string_equal(ops[3], "-");
}

/* One refused command line: CLI_OPT_ERROR and exactly this on stderr. */
static void refused(unsigned bits, char **argv, int argc, const char *msg)
{
    cli_parser p;
    cli_optval v[8];
    char *err;
    int n, rc;
    capture(&stderr);
    rc = parse(bits, argv, argc, &p, v, &n);
    err = release(&stderr);
    assert_int_equal(rc, CLI_OPT_ERROR);
    assert_string_equal(err, msg);
    free(err);
}

static void test_errors_say_what_and_where(void **state)
{
    char *a1[] = {"prog", "cmd", "--num", "41", NULL};
    char *a2[] = {"prog", "cmd", "--num", "-1", NULL};
    char *a3[] = {"prog", "cmd", "--num", "7x", NULL};
    char *a4[] = {"prog", "cmd", "--word", "Red", NULL};
    char *a5[] = {"prog", "cmd", "--num", NULL};
    char *a6[] = {"prog", "cmd", "--only-b", NULL};
    char *a7[] = {"prog", "cmd", "--flag=1", NULL};
    char *a8[] = {"prog", "cmd", "-x", NULL};
    char *a9[] = {"prog", "cmd", "-fx", NULL};
    char *a10[] = {"prog", "cmd", "--num", "99999999999999999999999", NULL};
    (void)state;
    refused(C_A, a1, 4, "prog: --num '41': expected 2..40\nTry 'prog cmd --help'.\n");
    refused(C_A, a2, 4, "prog: --num '-1': expected 2..40\nTry 'prog cmd --help'.\n");
    refused(C_A, a3, 4, "prog: --num '7x': expected 2..40\nTry 'prog cmd --help'.\n");
    refused(C_A, a4, 4,
            "prog: --word 'Red': expected red, green or blue\nTry 'prog cmd --help'.\n");
    refused(C_A, a5, 3, "prog: option '--num' needs an argument\nTry 'prog cmd --help'.\n");
    refused(C_A, a6, 3,
            "prog: --only-b does not apply to cmd (B's own)\nTry 'prog cmd --help'.\n");
    refused(C_A, a7, 3, "prog: option '--flag' takes no argument\nTry 'prog cmd --help'.\n");
    refused(C_A, a8, 3, "prog: unknown option '-x'\nTry 'prog cmd --help'.\n");
    refused(C_A, a9, 3, "prog: unknown option '-fx'\nTry 'prog cmd --help'.\n");
    refused(C_A, a10, 4,
            "prog: --num '99999999999999999999999': expected 2..40\nTry 'prog cmd --help'.\n");
}

static void test_did_you_mean(void **state)
{
    static const char *const names[] = {"grid", "summary", "decimals", "at",
                                        "footprint", "membership"};
    char *a1[] = {"prog", "cmd", "--nmu", "3", NULL};
    char *a2[] = {"prog", "cmd", "--colour=red", NULL};
    (void)state;
    assert_string_equal(cli_did_you_mean("gird", names, 6), "grid");
    assert_string_equal(cli_did_you_mean("sumary", names, 6), "summary");
    assert_string_equal(cli_did_you_mean("decimal", names, 6), "decimals");
    assert_string_equal(cli_did_you_mean("footprints", names, 6), "footprint");
    assert_string_equal(cli_did_you_mean("membreship", names, 6), "membership");
    assert_null(cli_did_you_mean("xyz", names, 6));
    assert_null(cli_did_you_mean("kind", names, 6));
    assert_null(cli_did_you_mean("", names, 0));
    refused(C_A, a1, 4,
            "prog: unknown option '--nmu' (did you mean '--num'?)\nTry 'prog cmd --help'.\n");
    refused(C_A, a2, 3, "prog: unknown option '--colour=red'\nTry 'prog cmd --help'.\n");
}

static void test_help_list(void **state)
{
    char *out;
    (void)state;
    capture(&stdout);
    cli_opt_help(stdout, tab, sizeof(tab) / sizeof(tab[0]), C_A, 12);
    out = release(&stdout);
    /* padded to 12, a longer label gets three spaces, continuation lines
     * indented to 14, options without a label or of other commands out */
    assert_string_equal(out, "  -f, --flag  a flag\n"
                             "  --num N     a number\n"
                             "              over two lines\n"
                             "  --word-with-a-long-label W   a colour\n");
    free(out);
}

/* The shared options into cli_opts, as it2n and it2nctl use them. */
static int common(unsigned bits, char **argv, int argc, cli_opts *o)
{
    const cli_optset sets[1] = {cli_common_opts};
    cli_parser p;
    cli_optval v;
    int id, rc;
    cli_opts_init(o);
    cli_opt_init(&p, "it2n", "plot", bits, sets, 1, argc, argv, 2);
    while ((id = cli_opt_next(&p, &v)) >= 0) {
        if ((rc = cli_common_take(&p, &v, o)) >= 0) {
            return rc;
        }
    }
    if (id == CLI_OPT_ERROR) {
        return 1;
    }
    return cli_common_finish(&p, o);
}

static void test_common_options(void **state)
{
    char *a1[] = {"it2n", "plot", "-o", "a.SVG", "--grid", "3x4", "--membership",
                  "F", "--footprint", "D,LL", "--decimals", "3", "--kind",
                  "bspline", "--size", "200x8000", NULL};
    char *a2[] = {"it2n", "plot", "-o", "a.png", "--interval", NULL};
    char *a3[] = {"it2n", "eval", "--at", "0.5,1", "--at", "0,0", NULL};
    cli_opts o;
    (void)state;
    assert_int_equal(common(CLI_O_PLOT | CLI_O_OUT | CLI_O_MEMB | CLI_O_GRID_OPT |
                                CLI_O_FP | CLI_O_KIND,
                            a1, 16, &o),
                     -1);
    assert_string_equal(o.output, "a.SVG");
    assert_int_equal(o.rows, 3);
    assert_int_equal(o.cols, 4);
    assert_int_equal(o.membership, 2);
    assert_int_equal(o.fpmask, (1u << IT2N_FP_D) | (1u << IT2N_FP_LL));
    assert_int_equal(o.decimals, 3);
    assert_int_equal(o.kind, CLI_KIND_BSPLINE);
    assert_int_equal(o.width, 200);
    assert_int_equal(o.height, 8000);
    free(o.at);
    /* defaults that depend on other options: --interval's grid and T */
    assert_int_equal(common(CLI_O_PLOT | CLI_O_OUT | CLI_O_MEMB | CLI_O_GRID_OPT, a2, 5, &o),
                     -1);
    assert_int_equal(o.rows, CLI_GRID_INTERVAL);
    assert_int_equal(o.membership, 0);
    free(o.at);
    assert_int_equal(common(CLI_O_AT_UW, a3, 6, &o), -1);
    assert_int_equal(o.nat, 2);
    assert_int_equal(o.at[0].a, (int64_t)1 << 31);
    assert_int_equal(o.at[0].b, (int64_t)1 << 32);
    free(o.at);
}

static void common_refused(unsigned bits, char **argv, int argc, const char *msg)
{
    cli_opts o;
    char *err;
    int rc;
    capture(&stderr);
    rc = common(bits, argv, argc, &o);
    err = release(&stderr);
    free(o.at);
    assert_int_equal(rc, 1);
    assert_string_equal(err, msg);
    free(err);
}

static void test_common_refused(void **state)
{
    const unsigned plot = CLI_O_PLOT | CLI_O_OUT | CLI_O_MEMB | CLI_O_GRID_OPT | CLI_O_FP;
    char *a1[] = {"it2n", "plot", "-o", "a.gif", NULL};
    char *a2[] = {"it2n", "plot", NULL};
    char *a3[] = {"it2n", "plot", "-o", "a.png", "--grid", "1002x2", NULL};
    char *a4[] = {"it2n", "plot", "-o", "a.png", "--interval", "--membership", "all", NULL};
    char *a5[] = {"it2n", "plot", "-o", "a.png", "--at", "0,0", NULL};
    char *a6[] = {"it2n", "plot", "--at", "1.5,0", NULL};
    char *a7[] = {"it2n", "plot", "--size", "199x300", "-o", "a.png", NULL};
    char *a8[] = {"it2n", "plot", "--footprint", "D,Q", NULL};
    (void)state;
    common_refused(plot, a1, 4,
                   "it2n: -o 'a.gif': the name must end in .png or .svg\nTry 'it2n plot --help'.\n");
    common_refused(plot, a2, 2,
                   "it2n: plot needs -o FILE.png or -o FILE.svg\nTry 'it2n plot --help'.\n");
    common_refused(plot, a3, 6,
                   "it2n: --grid '1002x2': at most 1001x1001 here\nTry 'it2n plot --help'.\n");
    common_refused(plot, a4, 7,
                   "it2n: --interval needs one membership: --membership T, I or F\n"
                   "Try 'it2n plot --help'.\n");
    common_refused(plot, a5, 6, "it2n: --at does not apply to plot\nTry 'it2n plot --help'.\n");
    common_refused(CLI_O_AT_UW, a6, 4,
                   "it2n: --at '1.5,0': parameters must lie in [0,1]\nTry 'it2n plot --help'.\n");
    common_refused(plot, a7, 6,
                   "it2n: --size '199x300': expected WxH with W, H in 200..8000\n"
                   "Try 'it2n plot --help'.\n");
    common_refused(plot, a8, 4,
                   "it2n: --footprint 'D,Q': expected names from LL,LR,L,D,R,RL,RR "
                   "separated by commas\nTry 'it2n plot --help'.\n");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scan_values_and_operands),
        cmocka_unit_test(test_errors_say_what_and_where),
        cmocka_unit_test(test_did_you_mean),
        cmocka_unit_test(test_help_list),
        cmocka_unit_test(test_common_options),
        cmocka_unit_test(test_common_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
