/*
 * The query points, shared by the images and the host program: (u, w) as
 * fractions of 65536 (exact in Q32, float and double). Four fixed points
 * (corners and centre), the rest from a fixed LCG.
 */
#ifndef BENCH_POINTS_H
#define BENCH_POINTS_H

#include <stdint.h>

#define BC_NPTS_MAX 32u  /* full run         */
#define BC_NPTS_QUICK 16u /* BENCH_QUICK=1    */
#define BC_NPTS_SMOKE 4u  /* make test smoke  */
#define BC_NPTS_HASH 16u  /* the bit-identity hash covers these */

static inline void bc_point(unsigned k, uint32_t *u16, uint32_t *w16)
{
    static const uint32_t fixed[4][2] = {{0u, 0u}, {65536u, 65536u}, {32768u, 32768u}, {0u, 65536u}};
    uint32_t s = 12345u;
    unsigned r;
    if (k < 4u) {
        *u16 = fixed[k][0];
        *w16 = fixed[k][1];
        return;
    }
    for (r = 0; r <= k; r++) {
        s = s * 1664525u + 1013904223u;
    }
    *u16 = (s >> 8) % 65537u;
    *w16 = (s >> 3) % 65537u;
}

#endif /* BENCH_POINTS_H */
