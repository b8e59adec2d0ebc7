/*
 * Reading and solving DATA.csv for both programs (it2n's commands and
 * it2nctl push), so a file is refused alike by either: errors as
 * FILE:LINE: ... on stderr.
 */
#include "cli.h"
#include "csv.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The B-spline kind's storage (up to 256 x 256 points) on the heap, and
 * its reader state (line numbers for messages). */
static cli_csv_reader g_csv;
static it2n_bspline_data g_bds;
static it2n_bspline_model g_bmdl;
static it2n_bspline_rec *g_brec;
static uint32_t *g_blines;
static int32_t *g_bcoef;

const char *cli_display_name(const char *path)
{
    return strcmp(path, "-") == 0 ? "<stdin>" : path;
}

static void report(const cli_csv_error *e, const char *name)
{
    char msg[512];
    cli_csv_message(e, name, msg, sizeof(msg));
    fprintf(stderr, "%s\n", msg);
}

/* Feed the file at path ("-": stdin) to csv; *rc the reader's answer.
 * CLI_EXIT_DATA after "NAME: cannot open/read error: why" on stderr. */
static int feed_file(const char *path, cli_csv_reader *csv, cli_csv_error *e, int *rc)
{
    const char *name = cli_display_name(path);
    FILE *f = strcmp(path, "-") == 0 ? stdin : fopen(path, "rb");
    char chunk[4096];
    size_t got;
    bool bad;
    if (f == NULL) {
        fprintf(stderr, "%s: cannot open: %s\n", name, strerror(errno));
        return CLI_EXIT_DATA;
    }
    *rc = IT2N_OK;
    while (*rc == IT2N_OK && (got = fread(chunk, 1, sizeof(chunk), f)) > 0) {
        *rc = cli_csv_feed(csv, chunk, got, e);
    }
    bad = *rc == IT2N_OK && ferror(f);
    if (bad) {
        fprintf(stderr, "%s: read error: %s\n", name, strerror(errno));
    }
    if (f != stdin) {
        fclose(f);
    }
    return bad ? CLI_EXIT_DATA : CLI_EXIT_OK;
}

int cli_load(const cli_opts *o, cli_csv_reader *csv, it2n_dataset *ds, it2n_model *mdl)
{
    const char *name = cli_display_name(o->path);
    cli_csv_error e;
    it2n_errinfo info;
    int rc;

    cli_csv_init(csv, o->flags);
    if (feed_file(o->path, csv, &e, &rc) != CLI_EXIT_OK) {
        return CLI_EXIT_DATA;
    }
    if (rc == IT2N_OK) {
        rc = cli_csv_finish(csv, ds, &e);
    }
    if (rc != IT2N_OK) {
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    it2n_model_init(mdl);
    rc = it2n_model_solve(mdl, ds, &info);
    if (rc != IT2N_OK) {
        cli_csv_locate(csv, &info, &e);
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

/* cli_load for the B-spline kind into g_bds, g_bmdl. */
static int load_bspline(const cli_opts *o)
{
    const char *name = cli_display_name(o->path);
    cli_csv_error e;
    it2n_errinfo info;
    size_t words;
    int rc;

    g_brec = malloc(CLI_CSV_BSPLINE_RECS * sizeof(*g_brec));
    g_blines = malloc(CLI_CSV_BSPLINE_LINES * sizeof(*g_blines));
    if (g_brec == NULL || g_blines == NULL) {
        fprintf(stderr, "it2n: out of memory for a B-spline data set\n");
        return CLI_EXIT_DATA;
    }
    cli_csv_init_bspline(&g_csv, g_brec, g_blines);
    if (feed_file(o->path, &g_csv, &e, &rc) != CLI_EXIT_OK) {
        return CLI_EXIT_DATA;
    }
    if (rc == IT2N_OK) {
        rc = cli_csv_finish_bspline(&g_csv, &g_bds, &e);
    }
    if (rc != IT2N_OK) {
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    words = IT2N_BSPLINE_MODEL_WORDS(g_bds.n, g_bds.m, g_bds.flags);
    g_bcoef = malloc(words * sizeof(*g_bcoef));
    if (g_bcoef == NULL) {
        fprintf(stderr, "it2n: out of memory for a B-spline model\n");
        return CLI_EXIT_DATA;
    }
    it2n_bspline_model_init(&g_bmdl, g_bcoef, words);
    rc = it2n_bspline_solve(&g_bmdl, &g_bds, &info);
    if (rc != IT2N_OK) {
        cli_csv_locate(&g_csv, &info, &e);
        report(&e, name);
        return CLI_EXIT_DATA;
    }
    return CLI_EXIT_OK;
}

static void free_bspline(void);

int cli_load_bspline(const cli_opts *o, const it2n_bspline_data **bds, const it2n_bspline_model **bmdl,
                     const cli_csv_reader **csv)
{
    int rc = load_bspline(o);
    *bds = &g_bds;
    *bmdl = &g_bmdl;
    *csv = &g_csv;
    return rc;
}

void cli_free_bspline(void)
{
    free_bspline();
}

static void free_bspline(void)
{
    free(g_brec);
    free(g_blines);
    free(g_bcoef);
    g_brec = NULL;
    g_blines = NULL;
    g_bcoef = NULL;
}
