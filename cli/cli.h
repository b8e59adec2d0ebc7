/*
 * it2n host CLI: options shared between option parsing (main.c) and the
 * commands (commands.c). The CLI holds no maths: it reads CSV, calls
 * firmware_core and prints CSV.
 */
#ifndef IT2N_CLI_H
#define IT2N_CLI_H

#include "it2n.h"

#include <stdbool.h>
#include <stddef.h>

#define IT2N_CLI_VERSION "0.1.0"

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
    const char *cmd;      /* subcommand name                  */
    const char *path;     /* DATA.csv, "-" for stdin          */
    unsigned flags;       /* extra IT2N_F_* (CHORD)           */
    unsigned decimals;    /* 6..9                             */
    bool summary;         /* eval/sample: interval summary    */
    unsigned rows, cols;  /* sample --grid                    */
    cli_at *at;           /* --at list (malloc'd)             */
    size_t nat;
} cli_opts;

/* Run the subcommand in o; returns an exit status. */
int cli_run(const cli_opts *o);

#endif /* IT2N_CLI_H */
