/*
 * Fuzz target for the CSV reader (cli/common/csv.c) and the text conversion
 * (firmware_core/it2n_text.c). Built two ways:
 *   - with clang -fsanitize=fuzzer (FUZZ_LIBFUZZER defined): `make fuzz`;
 *   - as a plain program (with ASan/UBSan) whose main() runs every file of
 *     the directories given on the command line: part of `make test`.
 * Properties checked (abort() on violation):
 *   - any input and any chunking: no crash, same result as one feed;
 *   - on success the data set is complete, within limits and solvable or
 *     rejected with an error code; error messages are NUL-terminated;
 *   - every token that parses as a value survives format(9) -> parse
 *     exactly; parsed parameters lie in [0, 1].
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "csv.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define REQUIRE(c)                                                           \
    do {                                                                     \
        if (!(c)) {                                                          \
            fprintf(stderr, "fuzz_csv: %s:%d: %s\n", __FILE__, __LINE__, #c); \
            abort();                                                         \
        }                                                                    \
    } while (0)

static cli_csv_reader g_a, g_b;
static it2n_dataset g_da, g_db;
static it2n_model g_mdl;

static int parse(cli_csv_reader *p, it2n_dataset *ds, const uint8_t *data,
                 size_t size, size_t chunk, cli_csv_error *e)
{
    size_t k;
    int rc = IT2N_OK;
    cli_csv_init(p, (size & 1u) ? IT2N_F_CHORD : 0u);
    for (k = 0; k < size && rc == IT2N_OK; k += chunk) {
        size_t n = size - k < chunk ? size - k : chunk;
        rc = cli_csv_feed(p, (const char *)data + k, n, e);
    }
    if (rc == IT2N_OK) {
        rc = cli_csv_finish(p, ds, e);
    }
    return rc;
}

static void fuzz_csv(const uint8_t *data, size_t size)
{
    cli_csv_error ea, eb;
    it2n_errinfo info;
    char msg[600];
    int ra, rb, n;

    ra = parse(&g_a, &g_da, data, size, size > 0 ? size : 1, &ea);
    rb = parse(&g_b, &g_db, data, size, 1u + size % 61u, &eb);
    REQUIRE(ra == rb);
    if (ra != IT2N_OK) {
        REQUIRE(ea.code == ra && eb.code == rb && ea.line == eb.line);
        n = cli_csv_message(&ea, "fuzz.csv", msg, sizeof(msg));
        REQUIRE(n > 0 && strlen(msg) < sizeof(msg));
        REQUIRE(strncmp(msg, "fuzz.csv", 8) == 0);
        return;
    }
    REQUIRE(memcmp(&g_da, &g_db, sizeof(g_da)) == 0);
    REQUIRE(g_da.n >= 1 && g_da.n <= IT2N_MAX_DEGREE);
    REQUIRE(g_da.m >= 1 && g_da.m <= IT2N_MAX_DEGREE);
    REQUIRE(it2n_dataset_missing(&g_da) == 0u);
    REQUIRE(it2n_dataset_check(&g_da, &info) == IT2N_OK);
    it2n_model_init(&g_mdl);
    if (it2n_model_solve(&g_mdl, &g_da, &info) == IT2N_OK) {
        it2n_point pt;
        REQUIRE(it2n_eval(&g_mdl, IT2N_PAR_ONE / 2, IT2N_PAR_ONE / 3, &pt, NULL) ==
                IT2N_OK);
    } else {
        REQUIRE(info.code < 0);
        REQUIRE(g_mdl.solved == 0);
        cli_csv_locate(&g_a, &info, &ea);
        n = cli_csv_message(&ea, "fuzz.csv", msg, sizeof(msg));
        REQUIRE(n > 0);
    }
}

/* The B-spline reader on the same input, two chunkings: same result; on
 * success a complete, checked data set that solves and evaluates. */
static void fuzz_bspline(const uint8_t *data, size_t size)
{
    static it2n_bspline_rec *rec[2];
    static uint32_t *lines[2];
    static int32_t *coef;
    it2n_bspline_data ds[2];
    cli_csv_error e[2];
    it2n_errinfo info;
    char msg[600];
    int rc[2], t;
    for (t = 0; t < 2; t++) {
        size_t chunk = t == 0 ? (size > 0 ? size : 1u) : 1u + size % 53u, k;
        if (rec[t] == NULL) {
            rec[t] = malloc(CLI_CSV_BSPLINE_RECS * sizeof(*rec[t]));
            lines[t] = malloc(CLI_CSV_BSPLINE_LINES * sizeof(*lines[t]));
            REQUIRE(rec[t] != NULL && lines[t] != NULL);
        }
        cli_csv_init_bspline(t == 0 ? &g_a : &g_b, rec[t], lines[t]);
        rc[t] = IT2N_OK;
        for (k = 0; k < size && rc[t] == IT2N_OK; k += chunk) {
            size_t n = size - k < chunk ? size - k : chunk;
            rc[t] = cli_csv_feed(t == 0 ? &g_a : &g_b, (const char *)data + k, n, &e[t]);
        }
        if (rc[t] == IT2N_OK) {
            rc[t] = cli_csv_finish_bspline(t == 0 ? &g_a : &g_b, &ds[t], &e[t]);
        }
    }
    REQUIRE(rc[0] == rc[1]);
    if (rc[0] != IT2N_OK) {
        REQUIRE(e[0].code == rc[0] && e[0].line == e[1].line);
        REQUIRE(cli_csv_message(&e[0], "fuzz.csv", msg, sizeof(msg)) > 0);
        REQUIRE(strncmp(msg, "fuzz.csv", 8) == 0);
        return;
    }
    REQUIRE(ds[0].n == ds[1].n && ds[0].m == ds[1].m && ds[0].flags == ds[1].flags);
    REQUIRE(memcmp(rec[0], rec[1], IT2N_BSPLINE_DATA_RECS(ds[0].n, ds[0].m, ds[0].flags) *
                                       sizeof(*rec[0])) == 0);
    REQUIRE(it2n_bspline_data_missing(&ds[0]) == 0u);
    REQUIRE(it2n_bspline_data_check(&ds[0], &info) == IT2N_OK);
    {
        size_t words = IT2N_BSPLINE_MODEL_WORDS(ds[0].n, ds[0].m, ds[0].flags);
        it2n_bspline_model mdl;
        it2n_point pt;
        free(coef);
        coef = malloc(words * sizeof(*coef));
        REQUIRE(coef != NULL);
        it2n_bspline_model_init(&mdl, coef, words);
        REQUIRE(it2n_bspline_solve(&mdl, &ds[0], &info) == IT2N_OK);
        REQUIRE(it2n_bspline_eval(&mdl, IT2N_PAR_ONE / 2, IT2N_PAR_ONE / 3, &pt,
                                  NULL) == IT2N_OK);
    }
}

static void fuzz_token(const char *s, size_t len)
{
    it2n_val v, back;
    it2n_par p;
    char buf[64];
    int n;
    if (it2n_parse_val(s, len, &v) == IT2N_OK) {
        const it2n_val lim = (it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE;
        REQUIRE(v >= -lim && v <= lim);
        n = it2n_format_val(buf, sizeof(buf), v, 9);
        REQUIRE(n > 0);
        REQUIRE(it2n_parse_val(buf, (size_t)n, &back) == IT2N_OK);
        REQUIRE(back == v);
    }
    {
        /* a membership parses iff a value does, to the same number at 2^-30:
         * its Q24 rounding is within one Q24 step of the Q24 parse */
        it2n_val q30;
        int rm = it2n_parse_memb(s, len, &q30), rv = it2n_parse_val(s, len, &back);
        REQUIRE(rm == rv);
        if (rm == IT2N_OK) {
            it2n_val r24 = (q30 + 32) >> 6;
            REQUIRE(r24 - back >= -1 && r24 - back <= 1);
        }
    }
    if (it2n_parse_par(s, len, &p) == IT2N_OK) {
        REQUIRE(p >= 0 && p <= IT2N_PAR_ONE);
        n = it2n_format_par(buf, sizeof(buf), p, 6);
        REQUIRE(n == 8);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t start = 0, k;
    fuzz_csv(data, size);
    fuzz_bspline(data, size);
    /* Tokens between separators, as the CSV reader and --at see them. */
    for (k = 0; k <= size; k++) {
        if (k == size || data[k] == ',' || data[k] == '\n') {
            fuzz_token((const char *)data + start, k - start);
            start = k + 1u;
        }
    }
    return 0;
}

#ifndef FUZZ_LIBFUZZER
#include <dirent.h>

static int run_file(const char *path)
{
    static uint8_t buf[1 << 20];
    FILE *f = fopen(path, "rb");
    size_t n;
    if (f == NULL) {
        fprintf(stderr, "fuzz_csv: cannot open %s\n", path);
        return 1;
    }
    n = fread(buf, 1, sizeof(buf), f);
    fclose(f);
    LLVMFuzzerTestOneInput(buf, n);
    return 0;
}

/* Run every regular file in the given directories (a fixed corpus). */
int main(int argc, char **argv)
{
    int k, files = 0, bad = 0;
    for (k = 1; k < argc; k++) {
        DIR *d = opendir(argv[k]);
        struct dirent *de;
        if (d == NULL) {
            fprintf(stderr, "fuzz_csv: cannot open directory %s\n", argv[k]);
            return 1;
        }
        while ((de = readdir(d)) != NULL) {
            char path[4096];
            if (de->d_name[0] == '.') {
                continue;
            }
            snprintf(path, sizeof(path), "%s/%s", argv[k], de->d_name);
            bad += run_file(path);
            files++;
        }
        closedir(d);
    }
    if (files == 0 || bad != 0) {
        fprintf(stderr, "fuzz_csv: %d files, %d unreadable\n", files, bad);
        return 1;
    }
    printf("fuzz_csv: corpus of %d files passed\n", files);
    return 0;
}
#endif
