/*
 * B-spline kind: evaluation, derivatives and grid sampling.
 *
 * On uniform knots the span of u is k = floor(u n) and its local parameter
 * t = u n - k, both exact from the Q32 parameter (one 32 x 32 product); the
 * four basis values are fixed cubics of t, computed once per query in Q30
 * and normalised to sum to exactly 2^30 (as the Bezier kind: constant data
 * stay constant and a stage-1 sum stays within the net). Each surface value
 * is then the Bezier kind's two short stages over a 4 x 4 window of the net:
 * 20 multiply-adds whatever the grid size.
 */
#include <stddef.h>
#include <string.h>

#include "it2n_internal.h"

#define Q30_ONE ((int64_t)1 << 30)

/* Span k (0..N-1) of u and t = u N - k in Q30 (0..2^30). */
static unsigned span_of(it2n_par u, unsigned N, uint32_t *t30)
{
    uint64_t p;
    unsigned k;
    if (u >= IT2N_PAR_ONE) {
        *t30 = (uint32_t)Q30_ONE;
        return N - 1u;
    }
    p = it2n_umul32((uint32_t)u, N); /* u < 2^32 here */
    k = (unsigned)(p >> 32);
    *t30 = (uint32_t)(((p & 0xFFFFFFFFu) + 2u) >> 2);
    return k;
}

/* round(a b / 2^30) for a, b in [0, 2^30]. */
static uint32_t q30mul(uint32_t a, uint32_t b)
{
    return (uint32_t)((it2n_umul32(a, b) + (1u << 29)) >> 30);
}

/* round(x / 6) for x in [0, 2^30]: x round(2^32 / 6) / 2^32. */
static int32_t div6(uint32_t x)
{
    return (int32_t)((it2n_umul32(x, 715827883u) + 0x80000000u) >> 32);
}

/*
 * Uniform cubic B-spline basis at t (Q30) into b[0..3] (Q30, sum exactly
 * 2^30): (1-t)^3/6, t^3/2 - t^2 + 2/3, the rest, t^3/6.
 */
static void basis(uint32_t t, int32_t b[4])
{
    uint32_t s = (uint32_t)Q30_ONE - t;
    uint32_t t2 = q30mul(t, t), t3 = q30mul(t2, t);
    uint32_t s3 = q30mul(q30mul(s, s), s);
    b[0] = div6(s3);
    b[3] = div6(t3);
    b[1] = (int32_t)(715827883 - (int64_t)t2 + (int64_t)((t3 + 1u) >> 1));
    b[2] = (int32_t)(Q30_ONE - b[0] - b[1] - b[3]);
}

/*
 * Derivative basis d/dt at t (Q30), in Q30: -(1-t)^2/2, 3t^2/2 - 2t,
 * the rest (they sum to 0), t^2/2. Absolute sum at most 1.5 (t = 1/2).
 */
static void dbasis(uint32_t t, int32_t db[4])
{
    uint32_t s = (uint32_t)Q30_ONE - t;
    uint32_t t2 = q30mul(t, t), s2 = q30mul(s, s);
    db[0] = -(int32_t)((s2 + 1u) >> 1);
    db[3] = (int32_t)((t2 + 1u) >> 1);
    db[1] = (int32_t)((int64_t)t2 + (int64_t)((t2 + 1u) >> 1) - 2 * (int64_t)t);
    db[2] = -(db[0] + db[1] + db[3]);
}

/* Stage 1: q[s] = sum_r cu[r] net[r][s] over the 4 x 4 window at win
 * (stride w), rounded by 2^s1: the mantissa scale for the basis (s1 = 30,
 * a convex combination), half of it for derivative weights (s1 = 31: their
 * absolute sum is at most 1.5 * 2^30). */
static void stage1(const int32_t *win, unsigned w, const int32_t cu[4], int s1, int32_t q[4])
{
    unsigned r, s;
    for (s = 0; s < 4u; s++) {
        const int32_t *p = win + s;
        int64_t acc = 0;
        for (r = 0; r < 4u; r++, p += w) {
            acc += it2n_smul32(cu[r], *p);
        }
        q[s] = (int32_t)((acc + ((int64_t)1 << (s1 - 1))) >> s1);
    }
}

/* Stage 2 (convex weights cw): the surface value in Q24. */
static it2n_val stage2(const int32_t q[4], const int32_t cw[4], int frac)
{
    int64_t acc = 0;
    unsigned s;
    for (s = 0; s < 4u; s++) {
        acc += it2n_smul32(cw[s], q[s]);
    }
    /* frac >= 0 (nets below 2^31 units): a right shift by >= 6 */
    return it2n__shift_round(acc, 30 + frac - IT2N_VAL_FRAC);
}

static int check_model(const it2n_bspline_model *mdl, it2n_errinfo *err)
{
    if (!mdl->solved || mdl->coef == NULL) {
        return it2n__fail(err, IT2N_ERR_STATE, -1, -1, -1, -1, 0, 0, 0);
    }
    return IT2N_OK;
}

#if IT2N_MUL_HALVES
/* stage1 (s1 = 30) then stage2 for the basis weights, which are never
 * negative (0..2^30): each product signed x unsigned, one sign correction
 * instead of two on ARMv6-M; the same exact products, so the same bits. */
static it2n_val window_halves(const int32_t *win, unsigned stride, const int32_t bu[4], const int32_t bw[4], int frac)
{
    int64_t acc = 0;
    unsigned r, s;
    for (s = 0; s < 4u; s++) {
        const int32_t *p = win + s;
        int64_t q = 0;
        for (r = 0; r < 4u; r++, p += stride) {
            q += it2n_mul32su(*p, (uint32_t)bu[r]);
        }
        acc += it2n_mul32su((int32_t)((q + ((int64_t)1 << 29)) >> 30), (uint32_t)bw[s]);
    }
    return it2n__shift_round(acc, 30 + frac - IT2N_VAL_FRAC);
}
#else
/* Values of `count` consecutive nets (win, win + size, ...; their exponents
 * frac[0..count)) into out[0..count): the same sums as stage1 and stage2,
 * so the same bits, with the row weights loaded once per run. ARMv6-M
 * keeps the loops (flash). */
#if defined(__GNUC__) && defined(__thumb2__) && (defined(__ARM_ARCH_7M__) || defined(__ARM_ARCH_7EM__))
#define IT2N__WINDOW_ASM 1
/* ARMv7-M: every net of the run in one assembly loop. Per net, four
 * columns of the window at p0 (rows p0, p0 + 4 sw, p2, p2 + 4 sw bytes,
 * both pointers advanced one word per column): q = (sum_r u_r c_r + 2^29)
 * >> 30 (low word), acc += bw_s q; then ((acc >> (sh - 1)) + 1) >> 1 with
 * sh = 30 + frac - IT2N_VAL_FRAC (it2n__shift_round's value; ARM's register shifts
 * fill with the sign from 32 on, so a shift beyond 62 gives 0 as it does).
 * GCC spills the weights of the C version; here the 13 registers hold
 * everything and the loop's state lives in ctx. */
typedef struct window_ctx {
    int32_t bw[4];      /*  0: column weights                 */
    const int32_t *win; /* 16: this net's window              */
    uint32_t size;      /* 20: bytes from one net to the next */
    const int8_t *frac; /* 24: this net's exponent            */
    it2n_val *out;      /* 28: this net's value               */
    uint32_t count;     /* 32: nets left                      */
} window_ctx;

/* clang-format off */
#define IT2N__ASM_COL(first, off)                                             \
    "ldr   %[t], [%[p0], %[sw], lsl #2]\n\t"                                  \
    "smull %[ql], %[qh], %[t], %[u1]\n\t"                                     \
    "ldr   %[t], [%[p0]], #4\n\t"                                             \
    "smlal %[ql], %[qh], %[t], %[u0]\n\t"                                     \
    "ldr   %[t], [%[p2], %[sw], lsl #2]\n\t"                                  \
    "smlal %[ql], %[qh], %[t], %[u3]\n\t"                                     \
    "ldr   %[t], [%[p2]], #4\n\t"                                             \
    "smlal %[ql], %[qh], %[t], %[u2]\n\t"                                     \
    "adds  %[ql], %[ql], #0x20000000\n\t"                                     \
    "adc   %[qh], %[qh], #0\n\t"                                              \
    "lsrs  %[ql], %[ql], #30\n\t"                                             \
    "orr   %[ql], %[ql], %[qh], lsl #2\n\t"                                   \
    "ldr   %[t], [%[cx], #" off "]\n\t"                                       \
    first " %[al], %[ah], %[t], %[ql]\n\t"
/* clang-format on */

static void window_run(const int32_t *win, size_t size, unsigned stride, const int32_t bu[4], const int32_t bw[4],
                       const int8_t *frac, it2n_val *out, unsigned count)
{
    window_ctx ctx;
    window_ctx *cx = &ctx;
    const int32_t *p0, *p2;
    uint32_t al, ah, ql, qh, t;
    if (count == 0u) {
        return;
    }
    memcpy(ctx.bw, bw, sizeof(ctx.bw));
    ctx.win = win;
    ctx.size = (uint32_t)(size * sizeof(int32_t));
    ctx.frac = frac;
    ctx.out = out;
    ctx.count = count;
    /* clang-format off */
    __asm__ volatile(
        "1:\n\t"
        "ldr   %[p0], [%[cx], #16]\n\t"
        "ldr   %[t], [%[cx], #20]\n\t"
        "add   %[t], %[t], %[p0]\n\t"
        "str   %[t], [%[cx], #16]\n\t"
        "add   %[p2], %[p0], %[sw], lsl #3\n\t"
        IT2N__ASM_COL("smull", "0") IT2N__ASM_COL("smlal", "4")
        IT2N__ASM_COL("smlal", "8") IT2N__ASM_COL("smlal", "12")
        /* t = sh - 1 = frac + 30 - IT2N_VAL_FRAC - 1 */
        "ldr   %[p0], [%[cx], #24]\n\t"
        "ldrsb %[t], [%[p0]], #1\n\t"
        "str   %[p0], [%[cx], #24]\n\t"
        "adds  %[t], %[t], %[bias]\n\t"
        /* (ah:al) >>= t, arithmetic, 0 < t */
        "subs  %[ql], %[t], #32\n\t"
        "bmi   2f\n\t"
        "asr   %[al], %[ah], %[ql]\n\t"
        "asr   %[ah], %[ah], #31\n\t"
        "b     3f\n"
        "2:\n\t"
        "rsb   %[ql], %[t], #32\n\t"
        "lsr   %[al], %[al], %[t]\n\t"
        "lsl   %[qh], %[ah], %[ql]\n\t"
        "orr   %[al], %[al], %[qh]\n\t"
        "asr   %[ah], %[ah], %[t]\n"
        "3:\n\t"
        /* (+1) >> 1 */
        "adds  %[al], %[al], #1\n\t"
        "adc   %[ah], %[ah], #0\n\t"
        "lsrs  %[al], %[al], #1\n\t"
        "orr   %[al], %[al], %[ah], lsl #31\n\t"
        "asr   %[ah], %[ah], #1\n\t"
        "ldr   %[p0], [%[cx], #28]\n\t"
        "strd  %[al], %[ah], [%[p0]], #8\n\t"
        "str   %[p0], [%[cx], #28]\n\t"
        "ldr   %[t], [%[cx], #32]\n\t"
        "subs  %[t], %[t], #1\n\t"
        "str   %[t], [%[cx], #32]\n\t"
        "bne   1b\n\t"
        : [al] "=&r"(al), [ah] "=&r"(ah), [ql] "=&r"(ql), [qh] "=&r"(qh),
          [t] "=&r"(t), [p0] "=&r"(p0), [p2] "=&r"(p2)
        : [sw] "r"(stride), [u0] "r"(bu[0]), [u1] "r"(bu[1]), [u2] "r"(bu[2]),
          [u3] "r"(bu[3]), [cx] "r"(cx), [bias] "i"(30 - IT2N_VAL_FRAC - 1)
        : "cc", "memory");
    /* clang-format on */
}
#undef IT2N__ASM_COL

/*
 * Type-1 on ARMv7-M: the whole query of footprint D in one assembly
 * function, registers fixed (r0 window, r1 ctx, r2 &v[D][0], r3 stride in
 * words, r4-r7 row weights, r8 row 2, r9 scratch, r10:r11 stage 1, r12:lr
 * stage 2). Per net the same sums and roundings as window_run, so the same
 * bits; the nets are unrolled (no loop state in memory), the six other
 * footprints are zeroed with store-multiples and the summary (every bound
 * is D's value) is D's T, I, F copied four times. A type-1 query's fixed
 * cost otherwise outweighs its five or six nets.
 */
typedef struct t1_ctx {
    int32_t bw[4];      /*  0: column weights                          */
    int32_t bu[4];      /* 16: row weights                             */
    uint32_t adv;       /* 32: bytes from the end of one window to the next net's */
    uint32_t stride;    /* 36: words per row                            */
    const int8_t *frac; /* 40: D's exponents by channel              */
    uint32_t has_z;     /* 44: nets x, y, z, T, I, F (else x, y, T, I, F, z = 0) */
} t1_ctx;

IT2N_STATIC_ASSERT(IT2N_FP_D == 3 && IT2N_CH_COUNT == 6 && IT2N_FP_COUNT == 7 && IT2N_CH_T == 3 &&
                       IT2N_VAL_FRAC == 24 && sizeof(it2n_val) == 8,
                   t1_asm_layout);
IT2N_STATIC_ASSERT(offsetof(it2n_point, sum) == 336 && offsetof(it2n_summary, upper_max) == 24 &&
                       offsetof(it2n_summary, lower_min) == 48 && offsetof(it2n_summary, lower_max) == 72,
                   t1_asm_point);
IT2N_STATIC_ASSERT(offsetof(t1_ctx, bu) == 16 && offsetof(t1_ctx, adv) == 32 && offsetof(t1_ctx, stride) == 36 &&
                       offsetof(t1_ctx, frac) == 40 && offsetof(t1_ctx, has_z) == 44,
                   t1_asm_ctx);

/* win: D's x window; v: &out->v[0][0]. */
void it2n__bspline_t1_v7m(const int32_t *win, const t1_ctx *cx, it2n_val *v);

/* clang-format off */
__asm__(
    ".syntax unified\n\t"
    ".section .text.it2n__bspline_t1_v7m,\"ax\",%progbits\n\t"
    ".align 2\n\t"
    ".global it2n__bspline_t1_v7m\n\t"
    ".hidden it2n__bspline_t1_v7m\n\t"
    ".thumb\n\t"
    ".thumb_func\n\t"
    ".type it2n__bspline_t1_v7m, %function\n"
    /* one column s: stage 1 over the four rows, rounded, times bw[s] */
    ".macro it2n__t1col mul, off\n\t"
    "ldr   r9, [r0, r3, lsl #2]\n\t"
    "smull r10, r11, r9, r5\n\t"
    "ldr   r9, [r0], #4\n\t"
    "smlal r10, r11, r9, r4\n\t"
    "ldr   r9, [r8, r3, lsl #2]\n\t"
    "smlal r10, r11, r9, r7\n\t"
    "ldr   r9, [r8], #4\n\t"
    "smlal r10, r11, r9, r6\n\t"
    "adds  r10, r10, #0x20000000\n\t"
    "adc   r11, r11, #0\n\t"
    "lsrs  r10, r10, #30\n\t"
    "orr   r10, r10, r11, lsl #2\n\t"
    "ldr   r9, [r1, #\\off]\n\t"
    "\\mul r12, lr, r9, r10\n\t"
    ".endm\n"
    /* one net into slot ch of D: shift by sh = 30 + frac - 24 rounding to
     * nearest as ((acc >> (sh - 1)) + 1) >> 1 (sh - 1 >= 32: from the high
     * word, |acc| < 2^62 so 32 bits hold it); then (next) on to the next
     * net's window */
    ".macro it2n__t1net ch, next\n\t"
    "it2n__t1col smull, 0\n\t"
    "it2n__t1col smlal, 4\n\t"
    "it2n__t1col smlal, 8\n\t"
    "it2n__t1col smlal, 12\n\t"
    "ldr   r9, [r1, #40]\n\t"
    "ldrsb r9, [r9, #\\ch]\n\t"
    "adds  r9, r9, #5\n\t"
    "subs  r10, r9, #32\n\t"
    "bmi   2f\n\t"
    "asr   r12, lr, r10\n\t"
    "adds  r12, r12, #1\n\t"
    "asr   r12, r12, #1\n\t"
    "asr   lr, r12, #31\n\t"
    "b     3f\n"
    "2:\n\t"
    "rsb   r10, r9, #32\n\t"
    "lsr   r12, r12, r9\n\t"
    "lsl   r11, lr, r10\n\t"
    "orr   r12, r12, r11\n\t"
    "asr   lr, lr, r9\n\t"
    "adds  r12, r12, #1\n\t"
    "adc   lr, lr, #0\n\t"
    "lsrs  r12, r12, #1\n\t"
    "orr   r12, r12, lr, lsl #31\n\t"
    "asr   lr, lr, #1\n"
    "3:\n\t"
    "strd  r12, lr, [r2, #(8 * \\ch)]\n\t"
    ".if \\next\n\t"
    "ldr   r9, [r1, #32]\n\t"
    "add   r0, r0, r9\n\t"
    "add   r8, r0, r3, lsl #3\n\t"
    ".endif\n\t"
    ".endm\n"
    "it2n__bspline_t1_v7m:\n\t"
    "push  {r4-r11, lr}\n\t"
    /* footprints LL, LR, L (bytes 0..143) and R, RL, RR (192..335) = 0 */
    "movs  r4, #0\n\t"
    "movs  r5, #0\n\t"
    "movs  r6, #0\n\t"
    "movs  r7, #0\n\t"
    "mov   r8, r4\n\t"
    "mov   r9, r4\n\t"
    "mov   r10, r4\n\t"
    "mov   r11, r4\n\t"
    "stmia r2!, {r4-r11}\n\t"
    "stmia r2!, {r4-r11}\n\t"
    "stmia r2!, {r4-r11}\n\t"
    "stmia r2!, {r4-r11}\n\t"
    "stmia r2!, {r4-r7}\n\t"
    "add   r12, r2, #48\n\t"
    "stmia r12!, {r4-r11}\n\t"
    "stmia r12!, {r4-r11}\n\t"
    "stmia r12!, {r4-r11}\n\t"
    "stmia r12!, {r4-r11}\n\t"
    "stmia r12!, {r4-r7}\n\t"
    "ldr   r3, [r1, #36]\n\t"
    "add   r12, r1, #16\n\t"
    "ldmia r12, {r4-r7}\n\t"
    "add   r8, r0, r3, lsl #3\n\t"
    "it2n__t1net 0, 1\n\t"
    "it2n__t1net 1, 1\n\t"
    "ldr   r9, [r1, #44]\n\t"
    "cmp   r9, #0\n\t"
    "beq   4f\n\t"
    "it2n__t1net 2, 1\n\t"
    "b     5f\n"
    "4:\n\t"
    "movs  r10, #0\n\t" /* z = 0 (r9 is) */
    "strd  r9, r10, [r2, #16]\n"
    "5:\n\t"
    "it2n__t1net 3, 1\n\t"
    "it2n__t1net 4, 1\n\t"
    "it2n__t1net 5, 0\n\t"
    /* the summary: upper_min, upper_max, lower_min, lower_max = T, I, F */
    "add   r9, r2, #24\n\t"
    "ldmia r9, {r3-r8}\n\t"
    "add   r9, r2, #192\n\t"
    "stmia r9!, {r3-r8}\n\t"
    "stmia r9!, {r3-r8}\n\t"
    "stmia r9!, {r3-r8}\n\t"
    "stmia r9!, {r3-r8}\n\t"
    "pop   {r4-r11, pc}\n\t"
    ".purgem it2n__t1net\n\t"
    ".purgem it2n__t1col\n\t"
    ".size it2n__bspline_t1_v7m, . - it2n__bspline_t1_v7m\n\t"
    ".text\n");
/* clang-format on */
#else
/* The two stages written out: the same sums as stage1 and stage2. */
IT2N_INLINE int64_t window_sum(const int32_t *p, unsigned stride, int32_t u0, int32_t u1, int32_t u2, int32_t u3,
                               const int32_t bw[4])
{
    const size_t st = stride;
    int64_t acc;
#define IT2N__COL(s)                                                                                       \
    ((int32_t)((it2n_smul32(u0, p[s]) + it2n_smul32(u1, p[st + (s)]) + it2n_smul32(u2, p[2u * st + (s)]) + \
                it2n_smul32(u3, p[3u * st + (s)]) + ((int64_t)1 << 29)) >>                                 \
               30))
    acc = it2n_smul32(bw[0], IT2N__COL(0));
    acc += it2n_smul32(bw[1], IT2N__COL(1));
    acc += it2n_smul32(bw[2], IT2N__COL(2));
    acc += it2n_smul32(bw[3], IT2N__COL(3));
#undef IT2N__COL
    return acc;
}

static void window_run(const int32_t *win, size_t size, unsigned stride, const int32_t bu[4], const int32_t bw[4],
                       const int8_t *frac, it2n_val *out, unsigned count)
{
    const int32_t u0 = bu[0], u1 = bu[1], u2 = bu[2], u3 = bu[3];
    unsigned k;
    for (k = 0; k < count; k++, win += size) {
        int64_t acc = window_sum(win, stride, u0, u1, u2, u3, bw);
        int sh = 30 + frac[k] - IT2N_VAL_FRAC; /* >= 6: frac >= 0 */
        /* it2n__shift_round's (acc + 2^(sh-1)) >> sh as ((acc >> (sh-1)) +
         * 1) >> 1: the same value, one variable 64-bit shift */
        out[k] = sh >= 63 ? 0 : ((acc >> (sh - 1)) + 1) >> 1;
    }
}
#endif
#endif

/* Values of every net at (u, w) into out->v (unused channels 0). The nets
 * are visited in storage order: footprint, then channel. */
static void eval_values(const it2n_bspline_model *mdl, it2n_par u, it2n_par w, it2n_point *out)
{
    int32_t bu[4], bw[4];
    uint32_t tu, tw;
    unsigned k = span_of(u, mdl->n, &tu), l = span_of(w, mdl->m, &tw);
    unsigned stride = mdl->m + 3u, fp, mask = it2n__fp_mask(mdl->flags);
    size_t size = (size_t)(mdl->n + 3u) * stride;
    const int32_t *win = mdl->coef + k * stride + l;
    basis(tu, bu);
    basis(tw, bw);
    if (mask != 0x7Fu) {
        /* type-1: the other footprints are 0 (explicit stores: a memset
         * call costs more than the six nets' values on ARMv7-M) */
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            it2n_val *o = out->v[fp];
            if (fp != IT2N_FP_D) {
                o[0] = o[1] = o[2] = o[3] = o[4] = o[5] = 0;
            }
        }
    }
#if !IT2N_MUL_HALVES
    if (mdl->flags & IT2N_F_Z) {
        /* every net in storage order is [fp][ch] order of frac and v too:
         * one run over all of them */
        fp = mask == 0x7Fu ? 0u : IT2N_FP_D;
        window_run(win, size, stride, bu, bw, mdl->frac[fp], out->v[fp],
                   (mask == 0x7Fu ? IT2N_FP_COUNT : 1u) * IT2N_CH_COUNT);
        return;
    }
#endif
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        it2n_val *o = out->v[fp];
        const int8_t *fr = mdl->frac[fp];
        if (!(mask & (1u << fp))) {
            continue;
        }
#if IT2N_MUL_HALVES
        {
            unsigned ch;
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                if (!it2n__ch_used(mdl->flags, ch)) {
                    o[ch] = 0;
                    continue;
                }
                o[ch] = window_halves(win, stride, bu, bw, fr[ch]);
                win += size;
            }
        }
#else
        /* x, y, then T, I, F: z is not stored */
        window_run(win, size, stride, bu, bw, fr, o, 2u);
        o[IT2N_CH_Z] = 0;
        window_run(win + 2u * size, size, stride, bu, bw, fr + 3, o + 3, 3u);
        win += 5u * size;
#endif
    }
}

#if defined(IT2N__WINDOW_ASM)
/* A type-1 query on ARMv7-M (it2n__bspline_t1_v7m): the values, summary and
 * out_of_range of eval_values + it2n__summarise_flags, bit for bit. */
static void eval_type1(const it2n_bspline_model *mdl, it2n_par u, it2n_par w, it2n_point *out)
{
    t1_ctx cx;
    uint32_t tu, tw;
    unsigned k = span_of(u, mdl->n, &tu), l = span_of(w, mdl->m, &tw);
    unsigned stride = mdl->m + 3u;
    const uint64_t one = (uint64_t)IT2N_VAL_ONE;
    const it2n_val *d = &out->v[IT2N_FP_D][IT2N_CH_T];
    basis(tu, cx.bu);
    basis(tw, cx.bw);
    cx.stride = stride;
    /* the kernel's row pointers end 4 words into the window */
    cx.adv = (uint32_t)((mdl->n + 3u) * stride * sizeof(int32_t) - 16u);
    cx.frac = mdl->frac[IT2N_FP_D];
    cx.has_z = mdl->flags & IT2N_F_Z;
    it2n__bspline_t1_v7m(mdl->coef + k * stride + l, &cx, &out->v[0][0]);
    out->out_of_range = (uint32_t)((uint64_t)d[0] > one) << (IT2N_FP_D * 3u) |
                        (uint32_t)((uint64_t)d[1] > one) << (IT2N_FP_D * 3u + 1u) |
                        (uint32_t)((uint64_t)d[2] > one) << (IT2N_FP_D * 3u + 2u);
}
#endif

int it2n_bspline_eval(const it2n_bspline_model *mdl, it2n_par u, it2n_par w, it2n_point *out, it2n_errinfo *err)
{
    int rc;
    if (mdl == NULL || out == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_model(mdl, err);
    if (rc == IT2N_OK) {
        rc = it2n__check_uw(u, w, err);
    }
    if (rc != IT2N_OK) {
        return rc;
    }
#if defined(IT2N__WINDOW_ASM)
    if (mdl->flags & IT2N_F_TYPE1) {
        eval_type1(mdl, u, w, out);
        return IT2N_OK;
    }
#endif
    eval_values(mdl, u, w, out);
    it2n__summarise_flags(mdl->flags, out);
    return IT2N_OK;
}

/*
 * One derivative value: sum_s cw[s] sum_r cu[r] net (cu the derivative
 * weights when s1 = 31, else cw) times N, in Q24. Both stages stay within
 * int64 (weights' absolute sums <= 1.5 * 2^30); the factor N is checked.
 * False if the result does not fit Q39.24.
 */
static bool deriv_value(const int32_t *win, unsigned stride, const int32_t cu[4], const int32_t cw[4], int s1, int frac,
                        unsigned N, it2n_val *out)
{
    int32_t q[4];
    int64_t acc = 0, v;
    unsigned s;
    stage1(win, stride, cu, s1, q);
    for (s = 0; s < 4u; s++) {
        acc += it2n_smul32(cw[s], q[s]);
    }
    /* acc is 2^(60 - s1) times the derivative's mantissa; |v| <= 1.5
     * max|coefficient| < 2^57 in Q24 */
    v = it2n__shift_round(acc, 60 - s1 + frac - IT2N_VAL_FRAC);
    {
        /* |v| N from two 32 x 32 products (no 64-bit multiply or divide
         * helper on ARMv6-M); N < 2^8 */
        uint64_t a = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
        uint64_t hi = it2n_umul32((uint32_t)(a >> 32), N);
        uint64_t lo = it2n_umul32((uint32_t)a, N), p;
        if (hi >> 31) {
            return false;
        }
        p = (hi << 32) + lo;
        if (p > (uint64_t)INT64_MAX) {
            return false;
        }
        *out = v < 0 ? -(int64_t)p : (int64_t)p;
    }
    return true;
}

int it2n_bspline_deriv(const it2n_bspline_model *mdl, it2n_par u, it2n_par w, it2n_point *du, it2n_point *dw,
                       it2n_errinfo *err)
{
    int32_t bu[4], bw[4], dbu[4], dbw[4];
    uint32_t tu, tw;
    unsigned k, l, stride, fp, ch, mask;
    int rc;
    if (mdl == NULL || du == NULL || dw == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_model(mdl, err);
    if (rc == IT2N_OK) {
        rc = it2n__check_uw(u, w, err);
    }
    if (rc != IT2N_OK) {
        return rc;
    }
    memset(du, 0, sizeof(*du));
    memset(dw, 0, sizeof(*dw));
    k = span_of(u, mdl->n, &tu);
    l = span_of(w, mdl->m, &tw);
    stride = mdl->m + 3u;
    mask = it2n__fp_mask(mdl->flags);
    basis(tu, bu);
    basis(tw, bw);
    dbasis(tu, dbu);
    dbasis(tw, dbw);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            const int32_t *win;
            if (!(mask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                continue;
            }
            win = it2n__bspline_net(mdl, fp, ch) + k * stride + l;
            if (!deriv_value(win, stride, dbu, bw, 31, mdl->frac[fp][ch], mdl->n, &du->v[fp][ch]) ||
                !deriv_value(win, stride, bu, dbw, 30, mdl->frac[fp][ch], mdl->m, &dw->v[fp][ch])) {
                return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, (int)fp, (int)ch, 0, 0, 0);
            }
        }
    }
    return IT2N_OK;
}

int it2n__bspline_eval_full(const it2n_bspline_model *mdl, unsigned fpmask, it2n_par u, it2n_par w, it2n_val *v,
                            it2n_val *du, it2n_val *dw, it2n_errinfo *err)
{
    int32_t bu[4], bw[4], dbu[4], dbw[4], q[4];
    uint32_t tu, tw;
    unsigned k = span_of(u, mdl->n, &tu), l = span_of(w, mdl->m, &tw);
    unsigned stride = mdl->m + 3u, fp, ch;
    basis(tu, bu);
    basis(tw, bw);
    dbasis(tu, dbu);
    dbasis(tw, dbw);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            unsigned at = fp * IT2N_CH_COUNT + ch;
            const int32_t *win;
            if (!(fpmask & (1u << fp)) || !it2n__ch_used(mdl->flags, ch)) {
                v[at] = du[at] = dw[at] = 0;
                continue;
            }
            win = it2n__bspline_net(mdl, fp, ch) + k * stride + l;
            stage1(win, stride, bu, 30, q);
            v[at] = stage2(q, bw, mdl->frac[fp][ch]);
            if (!deriv_value(win, stride, dbu, bw, 31, mdl->frac[fp][ch], mdl->n, &du[at]) ||
                !deriv_value(win, stride, bu, dbw, 30, mdl->frac[fp][ch], mdl->m, &dw[at])) {
                return it2n__fail(err, IT2N_ERR_OVERFLOW, -1, -1, (int)fp, (int)ch, 0, 0, 0);
            }
        }
    }
    return IT2N_OK;
}

/* Grid parameter k / (count - 1) in Q32 (as it2n_sample). */
static it2n_par grid_par(unsigned k, unsigned count)
{
    uint64_t d = count - 1u;
    return (it2n_par)it2n__udiv64_32(((uint64_t)k << IT2N_PAR_FRAC) + d / 2u, (uint32_t)d);
}

int it2n_bspline_sample(const it2n_bspline_model *mdl, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx,
                        it2n_errinfo *err)
{
    it2n_point pt;
    unsigned r, c;
    int rc;
    if (mdl == NULL || cb == NULL) {
        return it2n__fail(err, IT2N_ERR_INVAL, -1, -1, -1, -1, 0, 0, 0);
    }
    rc = check_model(mdl, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    rc = it2n__check_grid(rows, cols, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    for (r = 0; r < rows; r++) {
        it2n_par u = grid_par(r, rows);
        for (c = 0; c < cols; c++) {
            it2n_par w = grid_par(c, cols);
            int stop;
            /* the query itself: bit-identical to it2n_bspline_eval */
            eval_values(mdl, u, w, &pt);
            it2n__summarise_flags(mdl->flags, &pt);
            stop = cb(ctx, r, c, u, w, &pt);
            if (stop != 0) {
                return stop;
            }
        }
    }
    return IT2N_OK;
}
