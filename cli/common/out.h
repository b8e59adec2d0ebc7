/*
 * The output layer of it2n and it2nctl: the CSV rows both print (control
 * nets, evaluated points with their interval summary, located points), in
 * exact decimal text of the fixed-point values, so a file's answers and a
 * daemon's answers compare byte for byte.
 */
#ifndef IT2N_CLI_OUT_H
#define IT2N_CLI_OUT_H

#include "it2n.h"

#include <stdbool.h>

/* What the rows depend on: the model's z and type, and the options. */
typedef struct cli_out {
    bool z;            /* the model has z: a z column            */
    bool type1;        /* type-1: footprint D only               */
    bool summary;      /* --summary: interval bound rows         */
    unsigned fpmask;   /* --footprint bits, 0 = all              */
    unsigned decimals; /* --decimals (parameters: at least 6)    */
} cli_out;

/* Rows for a model of IT2N_F_* flags with these options. */
void cli_out_init(cli_out *w, unsigned flags, unsigned decimals, unsigned fpmask, bool summary);

/* True if footprint fp is in the model (and, selected, by --footprint). */
bool cli_out_has_fp(const cli_out *w, unsigned fp);
bool cli_out_selected(const cli_out *w, unsigned fp);

/* One value (Q24) or parameter (Q32, at least CLI_PAR_DECIMALS digits). */
void cli_put_val(it2n_val v, unsigned decimals);
void cli_put_par(it2n_par p, unsigned decimals);

/* "LEAD,x,y[,z],T,I,F TAIL" and a newline. */
void cli_put_header(const cli_out *w, const char *lead, const char *tail);

/* ",x,y[,z],T,I,F" of a channel vector. */
void cli_put_channels(const cli_out *w, const it2n_val *v);

/* A control net row "I,J,FP,x,y[,z],T,I,F". */
void cli_put_net_row(const cli_out *w, int i, int j, unsigned fp, const it2n_val *v);

/* The rows of one evaluated point: each selected footprint with its
 * out_of_range names (T|F or -), then, with --summary, upper_min,
 * upper_max, lower_min, lower_max. */
void cli_put_point(const cli_out *w, it2n_par u, it2n_par wp, const it2n_point *pt);

/* A locate row "X,Y,FP,U,W[,z],T,I,F,STATUS"; uw NULL: U, W empty (the
 * Modbus map does not carry them). */
void cli_put_locate_row(const cli_out *w, it2n_val x, it2n_val y, unsigned fp, const it2n_par *uw, const it2n_val *v,
                        const char *status);

/* An it2n_sample_cb for both programs' sample command: the rows of one
 * grid node (cli_put_point) with ctx the const cli_out *; non-zero
 * (CLI_EXIT_DATA, which stops the sample) once stdout has failed. */
int cli_put_sample_row(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par wp, const it2n_point *pt);

/* Flush stdout: CLI_EXIT_OK, or "PROG: write error" and 2. */
int cli_finish_output(const char *prog);

#endif /* IT2N_CLI_OUT_H */
