/*
 * FNV-1a 64 over the it2n results of one query (the 7 x 5 values and the
 * 12 summary values, Q24), so the images and the host can show the core's
 * results are bit-identical across targets.
 */
#ifndef BENCH_POINT_HASH_H
#define BENCH_POINT_HASH_H

#include <stdint.h>

#include "it2n_calls.h"

#define BC_FNV_OFFSET 14695981039346656037u
#define BC_FNV_PRIME 1099511628211u

static inline uint64_t bc_hash_i64(uint64_t h, int64_t v)
{
    uint64_t u = (uint64_t)v;
    unsigned b;
    for (b = 0; b < 8u; b++) {
        h ^= (u >> (8u * b)) & 0xFFu;
        h *= BC_FNV_PRIME;
    }
    return h;
}

/* Hash of the last bc_query's results, chained onto h. */
static inline uint64_t bc_hash_last_query(uint64_t h)
{
    unsigned fp, ch, w, k;
    for (fp = 0; fp < 7u; fp++) {
        for (ch = 0; ch < BENCH_CH; ch++) {
            h = bc_hash_i64(h, bc_value(fp, ch));
        }
    }
    for (w = 0; w < 4u; w++) {
        for (k = 0; k < 3u; k++) {
            h = bc_hash_i64(h, bc_summary(w, k));
        }
    }
    return h;
}

#endif /* BENCH_POINT_HASH_H */
