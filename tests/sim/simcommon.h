/* simcommon — helpers shared by the simulated PLC and instrument: CSV
 * loading through the CLI's reader (cli/common/csv.h) and small checks. */
#ifndef IT2N_SIMCOMMON_H
#define IT2N_SIMCOMMON_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "csv.h"
#include "it2n.h"

/* Load a data set CSV; exits with a message on error. */
static inline void sim_load_csv(const char *path, unsigned flags, it2n_dataset *ds)
{
    static cli_csv_reader p;
    cli_csv_error e;
    char buf[4096], msg[256];
    size_t n;
    FILE *f = fopen(path, "r");
    if (!f) {
        perror(path);
        exit(2);
    }
    cli_csv_init(&p, flags);
    while ((n = fread(buf, 1, sizeof buf, f)) > 0)
        cli_csv_feed(&p, buf, n, &e);
    fclose(f);
    if (cli_csv_finish(&p, ds, &e) != IT2N_OK) {
        cli_csv_message(&e, path, msg, sizeof msg);
        fprintf(stderr, "%s\n", msg);
        exit(2);
    }
}

#endif
