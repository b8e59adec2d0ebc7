/*
 * The benchmark's data sets (generated into datasets.c by datasets.py): one
 * row per grid point and footprint, channels x, y, T, I, F (no z).
 */
#ifndef BENCH_SET_H
#define BENCH_SET_H

#include <stdint.h>

#define BENCH_CH 5    /* x, y, T, I, F */
#define BENCH_NSETS 2 /* paper4, smooth7 */

typedef struct bench_row {
    uint8_t i, j, fp;         /* grid point, footprint (LL..RR = 0..6)    */
    int64_t q24[BENCH_CH];    /* Q24, rounded to nearest                  */
    double d[BENCH_CH];       /* the decimal value as a double            */
} bench_row;

typedef struct bench_set {
    const char *name;
    unsigned n, m, nrows;     /* degrees; nrows = (n+1)(m+1)*7            */
    const bench_row *rows;
#ifdef BENCH_HOST
    const long double (*ld)[BENCH_CH]; /* exact decimals, per row         */
#endif
} bench_set;

extern const bench_set bench_sets[BENCH_NSETS];

#endif /* BENCH_SET_H */
