/*
 * Internal: a tiny soft floating point, value = m * 2^e with a 62-bit
 * mantissa (|m| in [2^61, 2^62), or m == 0) and unit roundoff 2^-62.
 * Every operation rounds once and is exactly reproducible on every target.
 */
#ifndef IT2N_XF_H
#define IT2N_XF_H

#include <stdbool.h>
#include <stdint.h>

typedef struct xf {
    int64_t m;
    int32_t e;
} xf;

/* m * 2^e normalised; |m| < 2^63. */
xf xf_norm(int64_t m, int32_t e);
/* a * b, a + b, -a, a / b (b != 0), |a|. */
xf xf_mul(xf a, xf b);
xf xf_add(xf a, xf b);
xf xf_neg(xf a);
xf xf_div(xf a, xf b);
xf xf_abs(xf a);
/* |a| < |b| */
bool xf_abs_lt(xf a, xf b);
/* a in Q32, round to nearest; +-2^62 when |a| >= 2^30. */
int64_t xf_to_q32(xf a);

#endif /* IT2N_XF_H */
