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

typedef struct it2n__xf {
    int64_t m;
    int32_t e;
} it2n__xf;

/* *r = m * 2^e normalised; |m| < 2^63. */
void it2n__xf_set(it2n__xf *r, int64_t m, int32_t e);
/* *r = a * b, a + b, a - b, a / b (b != 0). */
void it2n__xf_mul(it2n__xf *r, const it2n__xf *a, const it2n__xf *b);
void it2n__xf_add(it2n__xf *r, const it2n__xf *a, const it2n__xf *b);
void it2n__xf_sub(it2n__xf *r, const it2n__xf *a, const it2n__xf *b);
void it2n__xf_div(it2n__xf *r, const it2n__xf *a, const it2n__xf *b);
/* |a| < |b| */
bool it2n__xf_abs_lt(const it2n__xf *a, const it2n__xf *b);
/* a in Q32, round to nearest; +-2^62 when |a| >= 2^30. */
int64_t it2n__xf_to_q32(const it2n__xf *a);

#endif /* IT2N_XF_H */
