/*
 * Internal: a tiny soft floating point, value = m * 2^e with a 62-bit
 * mantissa (|m| in [2^61, 2^62), or m == 0) and unit roundoff 2^-62.
 * Every operation rounds once and is exactly reproducible on every target.
 * Operands by pointer (results may alias them): 16-byte structs by value
 * cost a memcpy per argument on ARMv6-M.
 */
#ifndef IT2N_XF_H
#define IT2N_XF_H

#include <stdbool.h>
#include <stdint.h>

typedef struct xf {
    int64_t m;
    int32_t e;
} xf;

/* *r = m * 2^e normalised; |m| < 2^63. */
void xf_set(xf *r, int64_t m, int32_t e);
/* *r = a * b, a + b, a - b, a / b (b != 0). */
void xf_mul(xf *r, const xf *a, const xf *b);
void xf_add(xf *r, const xf *a, const xf *b);
void xf_sub(xf *r, const xf *a, const xf *b);
void xf_div(xf *r, const xf *a, const xf *b);
/* |a| < |b| */
bool xf_abs_lt(const xf *a, const xf *b);
/* a in Q32, round to nearest; +-2^62 when |a| >= 2^30. */
int64_t xf_to_q32(const xf *a);

#endif /* IT2N_XF_H */
