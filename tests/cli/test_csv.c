/*
 * cmocka tests of the streaming CSV reader (cli/common/csv.c): accepted layouts,
 * chunking independence, and every error class with its message and line.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "csv.h"

#define TEXT_MAX 65536

static cli_csv_reader g_p;
static it2n_dataset g_ds;
static char g_text[TEXT_MAX];

/* A valid (n+1)x(m+1) grid: x = 10 i + fp, y = 10 j + fp (nested), header
 * on line 1, row (i, j, fp) on line 2 + (i (m+1) + j) * nfp + fp. */
static const char *gen(unsigned n, unsigned m, bool type1, bool z)
{
    size_t len = 0;
    unsigned i, j, fp;
    len += (size_t)snprintf(g_text + len, TEXT_MAX - len, "%s\n",
                            z ? "i,j,footprint,x,y,z,T,I,F"
                              : "i,j,footprint,x,y,T,I,F");
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (type1 && fp != IT2N_FP_D) {
                    continue;
                }
                len += (size_t)snprintf(
                    g_text + len, TEXT_MAX - len, "%u,%u,%s,%u,%u%s,0.5,0.25,0.125\n",
                    i, j, it2n_fp_name(fp), 10u * i + fp, 10u * j + fp,
                    z ? ",1.5" : "");
            }
        }
    }
    return g_text;
}

/* Replace the line starting with `prefix` by `line` (no newline). */
static void replace_row(const char *prefix, const char *line)
{
    static char tmp[TEXT_MAX];
    char *at = strstr(g_text, prefix);
    char *end;
    assert_non_null(at);
    end = strchr(at, '\n');
    assert_non_null(end);
    snprintf(tmp, sizeof(tmp), "%.*s%s%s", (int)(at - g_text), g_text, line,
             end);
    strcpy(g_text, tmp);
}

static int parse(const char *text, size_t chunk, cli_csv_error *e)
{
    size_t len = strlen(text), k;
    int rc = IT2N_OK;
    cli_csv_init(&g_p, 0);
    for (k = 0; k < len && rc == IT2N_OK; k += chunk) {
        rc = cli_csv_feed(&g_p, text + k, len - k < chunk ? len - k : chunk,
                           e);
    }
    if (rc == IT2N_OK) {
        rc = cli_csv_finish(&g_p, &g_ds, e);
    }
    return rc;
}

/* Parse text and expect code, line and exact message. */
static void expect(const char *text, int code, unsigned long line,
                   const char *msg)
{
    cli_csv_error e;
    char buf[512];
    int rc = parse(text, 4096, &e);
    cli_csv_message(&e, "f.csv", buf, sizeof(buf));
    if (rc != code || strcmp(buf, msg) != 0 || e.line != line) {
        print_error("rc %d line %lu msg '%s'\n want %d line %lu '%s'\n", rc,
                    e.line, buf, code, line, msg);
    }
    assert_int_equal(rc, code);
    assert_int_equal(e.code, code);
    assert_int_equal(e.line, line);
    assert_string_equal(buf, msg);
}

static void test_ok_layouts(void **state)
{
    cli_csv_error e;
    (void)state;
    assert_int_equal(parse(gen(2, 1, false, false), 4096, &e), IT2N_OK);
    assert_int_equal(g_ds.n, 2);
    assert_int_equal(g_ds.m, 1);
    assert_int_equal(g_ds.flags, 0);
    assert_true(it2n_dataset_value(&g_ds, 2, 1, IT2N_FP_RR, IT2N_CH_X) ==
                26 * IT2N_VAL_ONE);
    assert_true(it2n_dataset_value(&g_ds, 2, 1, IT2N_FP_RR, IT2N_CH_T) == IT2N_VAL_ONE / 2);
    assert_int_equal(it2n_dataset_missing(&g_ds), 0);
    /* Line table: (1,0,L) is row 2 + (1*2+0)*7 + 2 = 18. */
    {
        it2n_errinfo info = {IT2N_ERR_ORDER, 1, 0, IT2N_FP_L, IT2N_CH_Y,
                             0, 0, 0};
        cli_csv_locate(&g_p, &info, &e);
        assert_int_equal(e.line, 18);
        assert_int_equal(e.field, 5);
    }

    assert_int_equal(parse(gen(1, 3, true, false), 4096, &e), IT2N_OK);
    assert_int_equal(g_ds.flags, IT2N_F_TYPE1);
    assert_int_equal(g_ds.m, 3);

    assert_int_equal(parse(gen(1, 1, false, true), 4096, &e), IT2N_OK);
    assert_int_equal(g_ds.flags, IT2N_F_Z);
    assert_true(it2n_dataset_value(&g_ds, 1, 1, IT2N_FP_D, IT2N_CH_Z) ==
                3 * IT2N_VAL_ONE / 2);

    /* --chord is passed through. */
    cli_csv_init(&g_p, IT2N_F_CHORD);
    gen(1, 1, true, false);
    assert_int_equal(cli_csv_feed(&g_p, g_text, strlen(g_text), &e), 0);
    assert_int_equal(cli_csv_finish(&g_p, &g_ds, &e), 0);
    assert_int_equal(g_ds.flags, IT2N_F_TYPE1 | IT2N_F_CHORD);
}

static void test_ok_syntax(void **state)
{
    static const char text[] =
        "\xEF\xBB\xBF# comment before the header\r\n"
        "\n"
        " i , j ,footprint, x, y, T, I, F \r\n"
        "# a comment\n"
        "0,0,D,0,0,0,0,0\r\n"
        "   \t\n"
        "0,1,D, 1 ,1,1,1,1\n"
        "  # indented comment\n"
        "1,0,D,+2,2e0,0.5,.5,5e-1\n"
        "1,1,D,3,3,1.0,0,0"; /* no final newline */
    cli_csv_error e;
    size_t chunk;
    (void)state;
    /* Any chunking gives the same data set. */
    for (chunk = 1; chunk <= sizeof(text); chunk += 7) {
        it2n_dataset first;
        assert_int_equal(parse(text, chunk, &e), IT2N_OK);
        assert_int_equal(g_ds.flags, IT2N_F_TYPE1);
        assert_true(it2n_dataset_value(&g_ds, 1, 0, IT2N_FP_D, IT2N_CH_F) ==
                    IT2N_VAL_ONE / 2);
        assert_true(it2n_dataset_value(&g_ds, 1, 1, IT2N_FP_D, IT2N_CH_X) ==
                    3 * IT2N_VAL_ONE);
        if (chunk == 1) {
            memcpy(&first, &g_ds, sizeof(first));
        }
        assert_int_equal(parse(text, 1, &e), IT2N_OK);
        (void)first;
    }
    /* Line numbers count comments and blank lines. */
    {
        it2n_errinfo info = {IT2N_ERR_RANGE, 1, 1, IT2N_FP_D, -1, 0, 0, 0};
        cli_csv_locate(&g_p, &info, &e);
        assert_int_equal(e.line, 10);
    }
}

static void test_err_header(void **state)
{
    (void)state;
    expect("", CLI_CSV_ERR_HEADER, 0,
           "f.csv: no header line (expected 'i,j,footprint,x,y,T,I,F' or "
           "'i,j,footprint,x,y,z,T,I,F')");
    expect("# only a comment\n\n", CLI_CSV_ERR_HEADER, 0,
           "f.csv: no header line (expected 'i,j,footprint,x,y,T,I,F' or "
           "'i,j,footprint,x,y,z,T,I,F')");
    expect("# c\ni,j,fp,x,y,T,I,F\n0,0,D,0,0,0,0,0\n", CLI_CSV_ERR_HEADER, 2,
           "f.csv:2: bad header 'i,j,fp,x,y,T,I,F' (expected "
           "'i,j,footprint,x,y,T,I,F' or 'i,j,footprint,x,y,z,T,I,F')");
    expect("i,j,footprint,x,y,t,i,f\n", CLI_CSV_ERR_HEADER, 1,
           "f.csv:1: bad header 'i,j,footprint,x,y,t,i,f' (expected "
           "'i,j,footprint,x,y,T,I,F' or 'i,j,footprint,x,y,z,T,I,F')");
}

/* Spreadsheet exports: every field quoted is read as unquoted; a quote
 * inside a field, or a ';'/tab separated file, gets its own message. */
static void test_quotes_and_separators(void **state)
{
    cli_csv_error e;
    it2n_dataset plain;
    char quoted[TEXT_MAX];
    size_t k, o = 0;
    (void)state;
    assert_int_equal(parse(gen(2, 1, false, true), 4096, &e), IT2N_OK);
    plain = g_ds;
    /* Wrap every field of gen()'s text in quotes (with spaces inside). */
    quoted[o++] = '"';
    for (k = 0; g_text[k] != '\0'; k++) {
        char c = g_text[k];
        if (c == ',') {
            memcpy(quoted + o, "\" ,\" ", 4);
            o += 4;
        } else if (c == '\n') {
            memcpy(quoted + o, "\"\n\"", 3);
            o += 3;
        } else {
            quoted[o++] = c;
        }
    }
    o -= 1; /* drop the '"' opened after the last line end */
    quoted[o] = '\0';
    assert_int_equal(parse(quoted, 7, &e), IT2N_OK);
    assert_memory_equal(&g_ds, &plain, sizeof(plain));

    expect("i,j,footprint,x,y,T,I,F\n0,0,\"D,1\",0,0,0,0,0\n",
           CLI_CSV_ERR_QUOTE, 2,
           "f.csv:2: field 3: bad quoting '\"D' (a field may be wrapped whole "
           "in \"...\", but never holds '\"' or ',')");
    expect("i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,\"0\"\"5\",0\n",
           CLI_CSV_ERR_QUOTE, 2,
           "f.csv:2: field 7: bad quoting '\"0\"\"5\"' (a field may be wrapped "
           "whole in \"...\", but never holds '\"' or ',')");
    expect("\"i\",\"j,footprint,x,y,T,I,F\n", CLI_CSV_ERR_QUOTE, 1,
           "f.csv:1: field 2: bad quoting '\"j' (a field may be wrapped whole "
           "in \"...\", but never holds '\"' or ',')");
    expect("i;j;footprint;x;y;T;I;F\n0;0;D;0;0;0,5;0,5;0,5\n",
           CLI_CSV_ERR_SEPARATOR, 1,
           "f.csv:1: fields separated by ';', not ',' (save the CSV with ',' "
           "as separator and '.' as decimal point; expected "
           "'i,j,footprint,x,y,T,I,F')");
    expect("i\tj\tfootprint\tx\ty\tT\tI\tF\n", CLI_CSV_ERR_SEPARATOR, 1,
           "f.csv:1: fields separated by tabs, not ',' (save the CSV with ',' "
           "as separator and '.' as decimal point; expected "
           "'i,j,footprint,x,y,T,I,F')");
}

static void test_err_rows(void **state)
{
    (void)state;
    gen(1, 1, false, false);
    replace_row("0,1,L,", "0,1,L,1,2,0.5,0.5");
    expect(g_text, CLI_CSV_ERR_FIELDS, 11,
           "f.csv:11: 7 fields, expected 8 (i,j,footprint,x,y,T,I,F)");

    gen(1, 1, false, true);
    replace_row("0,0,LL,", "0,0,LL,1,2,3,4,5,6,7,8,9,10");
    expect(g_text, CLI_CSV_ERR_FIELDS, 2,
           "f.csv:2: more than 10 fields, expected 9 "
           "(i,j,footprint,x,y,z,T,I,F)");

    gen(1, 1, false, false);
    replace_row("1,0,R,", "1,0,R,abc,14,0.5,0.5,0.5");
    expect(g_text, CLI_CSV_ERR_NUMBER, 20,
           "f.csv:20: x='abc' is not a decimal number at (i=1,j=0,R)");

    gen(1, 1, false, false);
    replace_row("1,1,D,", "1,1,D,13,13,0.5,,0.5");
    expect(g_text, CLI_CSV_ERR_NUMBER, 26,
           "f.csv:26: I='' is not a decimal number at (i=1,j=1,D)");

    gen(1, 1, false, false);
    replace_row("1,1,D,", "8,1,D,13,13,0.5,0.5,0.5");
    expect(g_text, CLI_CSV_ERR_INDEX, 26,
           "f.csv:26: i='8' is not a grid index 0..7 (IT2N_MAX_DEGREE)");

    gen(1, 1, false, false);
    replace_row("1,1,D,", "1,-1,D,13,13,0.5,0.5,0.5");
    expect(g_text, CLI_CSV_ERR_INDEX, 26,
           "f.csv:26: j='-1' is not a grid index 0..7 (IT2N_MAX_DEGREE)");

    gen(1, 1, false, false);
    replace_row("1,1,D,", "1,1,DD,13,13,0.5,0.5,0.5");
    expect(g_text, CLI_CSV_ERR_FOOTPRINT, 26,
           "f.csv:26: unknown footprint 'DD' (expected one of LL, LR, L, D, "
           "R, RL, RR)");
}

static void test_err_lines(void **state)
{
    char longline[400];
    (void)state;
    memset(longline, ' ', sizeof(longline));
    memcpy(longline, "0,0,LL", 6);
    longline[300] = '\0';
    gen(1, 1, false, false);
    replace_row("0,0,LL,", longline);
    expect(g_text, CLI_CSV_ERR_LONG, 2, "f.csv:2: line longer than 256 bytes");

    /* Exactly 256 bytes plus CRLF is fine. */
    memset(longline, ' ', sizeof(longline));
    memcpy(longline, "0,0,LL,0,0,0.5,0.25,0.125", 25);
    memcpy(longline + 256, "\r", 2);
    gen(1, 1, false, false);
    replace_row("0,0,LL,", longline);
    {
        cli_csv_error e;
        assert_int_equal(parse(g_text, 4096, &e), IT2N_OK);
    }

    gen(1, 1, false, false);
    replace_row("0,0,LR,", "0,0,LR,1,1,0.5\x01,0.25,0.125");
    expect(g_text, CLI_CSV_ERR_BINARY, 3, "f.csv:3: control byte 0x01 in line");

    expect("i,j,footprint,x,y,T,I,F\n# nothing\n", CLI_CSV_ERR_EMPTY, 0,
           "f.csv: no data rows after the header");
    expect("i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0,0,0\n0,1,D,0,1,0,0,0\n",
           CLI_CSV_ERR_DEGREE, 0,
           "f.csv: every row has i=0: need 2 to 8 grid points per direction "
           "(degree 1..7)");
    expect("i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0,0,0\n1,0,D,0,1,0,0,0\n",
           CLI_CSV_ERR_DEGREE, 0,
           "f.csv: every row has j=0: need 2 to 8 grid points per direction "
           "(degree 1..7)");
}

/* Memberships are read to 2^-30 (it2n.h, IT2N_MEMB_FRAC), coordinates to
 * 2^-24: 9-decimal memberships keep their digits, and one Q30 step above 1
 * is out of range. */
static void test_memb_q30(void **state)
{
    cli_csv_error e;
    (void)state;
    gen(1, 1, true, false);
    replace_row("1,0,D,", "1,0,D,10,0,0.123456789,0.000000001,0.9999999995");
    assert_int_equal(parse(g_text, 4096, &e), IT2N_OK);
    /* round(0.123456789 2^30) = 132560718 (Q24 would keep 2071261 * 64) */
    assert_true(it2n_dataset_value_fine(&g_ds, 1, 0, IT2N_FP_D, IT2N_CH_T) == 132560718);
    assert_true(it2n_dataset_value_fine(&g_ds, 1, 0, IT2N_FP_D, IT2N_CH_I) == 1);
    assert_true(it2n_dataset_value_fine(&g_ds, 1, 0, IT2N_FP_D, IT2N_CH_F) ==
                IT2N_MEMB_ONE - 1);
    /* the Q24 view rounds to nearest */
    assert_true(it2n_dataset_value(&g_ds, 1, 0, IT2N_FP_D, IT2N_CH_T) == 2071261);
    assert_true(it2n_dataset_value(&g_ds, 1, 0, IT2N_FP_D, IT2N_CH_F) == IT2N_VAL_ONE);
    /* 1 + 1e-10 rounds to 1 at 2^-30; 1 + 1e-9 does not */
    replace_row("1,0,D,", "1,0,D,10,0,1.0000000001,0,0");
    assert_int_equal(parse(g_text, 4096, &e), IT2N_OK);
    replace_row("1,0,D,", "1,0,D,10,0,1.000000001,0,0");
    expect(g_text, IT2N_ERR_RANGE, 4,
           "f.csv:4: T=1.000000001 outside [0,1] at (i=1,j=0,D)");
    /* the B-spline reader stores them alike */
    {
        it2n_bspline_rec *scratch = malloc(CLI_CSV_BSPLINE_RECS * sizeof(*scratch));
        uint32_t *lines = malloc(CLI_CSV_BSPLINE_LINES * sizeof(*lines));
        it2n_bspline_data bds;
        assert_true(scratch != NULL && lines != NULL);
        it2n_val v[IT2N_CH_COUNT];
        replace_row("1,0,D,", "1,0,D,10,0,0.123456789,0.000000001,0.9999999995");
        cli_csv_init_bspline(&g_p, scratch, lines);
        assert_int_equal(cli_csv_feed(&g_p, g_text, strlen(g_text), &e), IT2N_OK);
        assert_int_equal(cli_csv_finish_bspline(&g_p, &bds, &e), IT2N_OK);
        it2n_bspline_data_get_fine(&bds, 1, 0, IT2N_FP_D, v);
        assert_true(v[IT2N_CH_T] == 132560718 && v[IT2N_CH_I] == 1 &&
                    v[IT2N_CH_F] == IT2N_MEMB_ONE - 1);
        it2n_bspline_data_get(&bds, 1, 0, IT2N_FP_D, v);
        assert_true(v[IT2N_CH_T] == 2071261 && v[IT2N_CH_F] == IT2N_VAL_ONE);
        free(scratch);
        free(lines);
    }
}

static void test_err_values(void **state)
{
    (void)state;
    gen(2, 1, false, false);
    replace_row("2,1,RL,", "2,1,RL,25,15,1.2,0.4,0.1");
    expect(g_text, IT2N_ERR_RANGE, 42,
           "f.csv:42: T=1.2 outside [0,1] at (i=2,j=1,RL)");

    gen(2, 1, false, false);
    replace_row("0,1,D,", "0,1,D,3,13,0.5,0.5,-0.000001");
    expect(g_text, IT2N_ERR_RANGE, 12,
           "f.csv:12: F=-0.000001 outside [0,1] at (i=0,j=1,D)");

    gen(1, 1, false, false);
    replace_row("1,1,RR,", "1,1,RR,9e9,16,0.5,0.5,0.5");
    expect(g_text, IT2N_ERR_RANGE, 29,
           "f.csv:29: x=9e9 outside [-8388607,8388607] at (i=1,j=1,RR)");

    gen(1, 1, false, false);
    replace_row("1,1,RR,", "1,1,RR,16,16,0.5,0.5,0.5\n0,1,L,12,12,0.5,0.5,0.5");
    expect(g_text, IT2N_ERR_DUPLICATE, 30,
           "f.csv:30: duplicate row at (i=0,j=1,L) (first on line 11)");

    gen(1, 1, false, false);
    replace_row("1,1,RR,", "# RR dropped");
    expect(g_text, IT2N_ERR_MISSING, 0,
           "f.csv: missing row at (i=1,j=1,RR) (rows other than D are "
           "present, so every grid point needs all seven footprints)");

    gen(1, 1, true, false);
    replace_row("1,0,D,", "# dropped");
    expect(g_text, IT2N_ERR_MISSING, 0, "f.csv: missing row at (i=1,j=0,D)");

    /* y of (1,0,RL) = 3 is below R's y = 4. */
    gen(1, 1, false, false);
    replace_row("1,0,RL,", "1,0,RL,15,3,0.5,0.5,0.5");
    expect(g_text, IT2N_ERR_ORDER, 21,
           "f.csv:21: y=3 below R's y=4: footprints must nest "
           "LL<=LR<=L<=D<=R<=RL<=RR at (i=1,j=0,RL)");
}

static void test_sticky_and_untouched(void **state)
{
    cli_csv_error e, e2;
    it2n_dataset before;
    (void)state;
    memset(&g_ds, 0x5A, sizeof(g_ds));
    memcpy(&before, &g_ds, sizeof(before));
    cli_csv_init(&g_p, 0);
    assert_int_equal(cli_csv_feed(&g_p, "i,j,footprint,x,y,T,I,F\nX\n", 26, &e),
                     CLI_CSV_ERR_FIELDS);
    assert_int_equal(cli_csv_feed(&g_p, "0,0,D,0,0,0,0,0\n", 16, &e2),
                     CLI_CSV_ERR_FIELDS);
    assert_int_equal(e2.line, 2);
    assert_int_equal(cli_csv_finish(&g_p, &g_ds, &e2), CLI_CSV_ERR_FIELDS);
    assert_memory_equal(&before, &g_ds, sizeof(before));
}

static void test_solve_errors_map_to_lines(void **state)
{
    static it2n_model mdl;
    cli_csv_error e;
    it2n_errinfo info;
    char buf[512];
    static const char text[] = "i,j,footprint,x,y,T,I,F\n"
                               "0,0,D,1,1,0,0,0\n"
                               "0,1,D,1,1,0,0,0\n"
                               "1,0,D,1,1,0,0,0\n"
                               "1,1,D,1,1,0,0,0\n";
    (void)state;
    cli_csv_init(&g_p, IT2N_F_CHORD);
    assert_int_equal(cli_csv_feed(&g_p, text, strlen(text), &e), 0);
    assert_int_equal(cli_csv_finish(&g_p, &g_ds, &e), 0);
    it2n_model_init(&mdl);
    assert_int_equal(it2n_model_solve(&mdl, &g_ds, &info), IT2N_ERR_DEGENERATE);
    cli_csv_locate(&g_p, &info, &e);
    cli_csv_message(&e, "f.csv", buf, sizeof(buf));
    assert_non_null(strstr(buf, "f.csv"));
    assert_non_null(strstr(buf, "degenerate chord-length parameterisation"));
    assert_int_equal(mdl.solved, 0);
}

/* The B-spline kind's reader: grids beyond the Bezier limit, records
 * compacted in place to the file's grid, lines of late errors, limits. */
static void test_bspline_reader(void **state)
{
    static it2n_bspline_rec *rec;
    static uint32_t *lines;
    it2n_bspline_data ds;
    cli_csv_error e;
    it2n_val v[IT2N_CH_COUNT];
    char msg[512];
    size_t k, len;
    int rc = IT2N_OK;
    unsigned pass;
    (void)state;
    rec = malloc(CLI_CSV_BSPLINE_RECS * sizeof(*rec));
    lines = malloc(CLI_CSV_BSPLINE_LINES * sizeof(*lines));
    assert_true(rec != NULL && lines != NULL);
    for (pass = 0; pass < 2; pass++) {
        bool type1 = pass == 0;
        gen(12, 9, type1, !type1);
        len = strlen(g_text);
        cli_csv_init_bspline(&g_p, rec, lines);
        for (k = 0; k < len && rc == IT2N_OK; k += 7) {
            rc = cli_csv_feed(&g_p, g_text + k, len - k < 7 ? len - k : 7, &e);
        }
        assert_int_equal(rc, IT2N_OK);
        assert_int_equal(cli_csv_finish_bspline(&g_p, &ds, &e), IT2N_OK);
        assert_int_equal(ds.n, 12);
        assert_int_equal(ds.m, 9);
        assert_int_equal(ds.flags, type1 ? IT2N_F_TYPE1 : IT2N_F_Z);
        assert_int_equal(it2n_bspline_data_missing(&ds), 0);
        it2n_bspline_data_get(&ds, 11, 7, IT2N_FP_D, v);
        assert_true(v[IT2N_CH_X] == 113 * IT2N_VAL_ONE);
        assert_true(v[IT2N_CH_Y] == 73 * IT2N_VAL_ONE);
        assert_true(v[IT2N_CH_I] == IT2N_VAL_ONE / 4);
        if (!type1) {
            it2n_bspline_data_get(&ds, 12, 9, IT2N_FP_RR, v);
            assert_true(v[IT2N_CH_X] == 126 * IT2N_VAL_ONE);
            assert_true(v[IT2N_CH_Z] == 3 * IT2N_VAL_ONE / 2);
            /* (3,2,R) is on line 2 + (3*10+2)*7 + 4 */
            {
                it2n_errinfo info = {IT2N_ERR_ORDER, 3, 2, IT2N_FP_R,
                                     IT2N_CH_Z, 0, 0, 0};
                cli_csv_locate(&g_p, &info, &e);
                assert_int_equal(e.line, 2 + 32 * 7 + 4);
                assert_int_equal(e.field, 6);
            }
        }
    }
    /* index limit and the Bezier reader's refusal of a B-spline read */
    cli_csv_init_bspline(&g_p, rec, lines);
    strcpy(g_text, "i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,0.5,0.5\n"
                   "255,1,D,0,0,0.5,0.5,0.5\n256,0,D,0,0,0.5,0.5,0.5\n");
    assert_int_equal(cli_csv_feed(&g_p, g_text, strlen(g_text), &e),
                     CLI_CSV_ERR_INDEX);
    assert_int_equal(e.line, 4);
    cli_csv_message(&e, "f.csv", msg, sizeof(msg));
    assert_string_equal(msg, "f.csv:4: i='256' is not a grid index 0..255 "
                             "(IT2N_BSPLINE_MAX_N)");
    /* a missing row found at the end names its (i, j, footprint) */
    cli_csv_init_bspline(&g_p, rec, lines);
    strcpy(g_text, "i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,0.5,0.5\n"
                   "0,1,D,0,1,0.5,0.5,0.5\n1,1,D,1,1,0.5,0.5,0.5\n");
    assert_int_equal(cli_csv_feed(&g_p, g_text, strlen(g_text), &e), IT2N_OK);
    assert_int_equal(cli_csv_finish_bspline(&g_p, &ds, &e), IT2N_ERR_MISSING);
    cli_csv_message(&e, "f.csv", msg, sizeof(msg));
    assert_string_equal(msg, "f.csv: missing row at (i=1,j=0,D)");
    /* every row with i = 0: a direction needs 2 points */
    cli_csv_init_bspline(&g_p, rec, lines);
    strcpy(g_text, "i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,0.5,0.5\n"
                   "0,1,D,0,1,0.5,0.5,0.5\n");
    assert_int_equal(cli_csv_feed(&g_p, g_text, strlen(g_text), &e), IT2N_OK);
    assert_int_equal(cli_csv_finish_bspline(&g_p, &ds, &e), CLI_CSV_ERR_DEGREE);
    cli_csv_message(&e, "f.csv", msg, sizeof(msg));
    assert_string_equal(msg, "f.csv: every row has i=0: need 2 to 256 grid "
                             "points per direction");
    /* the kinds' finish calls do not mix */
    cli_csv_init(&g_p, 0);
    assert_int_equal(cli_csv_finish_bspline(&g_p, &ds, &e), IT2N_ERR_INVAL);
    cli_csv_init_bspline(&g_p, rec, lines);
    assert_int_equal(cli_csv_finish(&g_p, &g_ds, &e), IT2N_ERR_INVAL);
    free(rec);
    free(lines);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ok_layouts),
        cmocka_unit_test(test_ok_syntax),
        cmocka_unit_test(test_err_header),
        cmocka_unit_test(test_quotes_and_separators),
        cmocka_unit_test(test_err_rows),
        cmocka_unit_test(test_err_lines),
        cmocka_unit_test(test_memb_q30),
        cmocka_unit_test(test_err_values),
        cmocka_unit_test(test_sticky_and_untouched),
        cmocka_unit_test(test_solve_errors_map_to_lines),
        cmocka_unit_test(test_bspline_reader),
    };
    return cmocka_run_group_tests_name("cli_csv", tests, NULL, NULL);
}
