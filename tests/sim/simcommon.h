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
    static csv_reader p;
    csv_error e;
    char buf[4096], msg[256];
    size_t n;
    FILE *f = fopen(path, "r");
    if (!f) {
        perror(path);
        exit(2);
    }
    csv_init(&p, flags);
    while ((n = fread(buf, 1, sizeof buf, f)) > 0)
        csv_feed(&p, buf, n, &e);
    fclose(f);
    if (csv_finish(&p, ds, &e) != IT2N_OK) {
        csv_message(&e, path, msg, sizeof msg);
        fprintf(stderr, "%s\n", msg);
        exit(2);
    }
}

/* The data set as the serial protocol carries it: memberships rounded to
 * Q24 (it2n_dataset_get), stored again. What a model filled over a link
 * holds, where the CSV reader keeps 2^-30 (it2n.h, IT2N_MEMB_FRAC). */
static inline void sim_round_q24(it2n_dataset *ds)
{
    for (unsigned i = 0; i <= ds->n; i++)
        for (unsigned j = 0; j <= ds->m; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                it2n_errinfo e;
                if (!(ds->present[i][j] & (1u << fp)))
                    continue;
                it2n_dataset_get(ds, i, j, fp, v);
                if (it2n_dataset_put(ds, i, j, fp, v, true, &e) != IT2N_OK) {
                    fprintf(stderr, "sim_round_q24: put (%u,%u,%u) refused\n", i, j, fp);
                    exit(2);
                }
            }
}

#endif
