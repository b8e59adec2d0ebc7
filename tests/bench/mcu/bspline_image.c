/*
 * B-spline kind on emulated Cortex-M (issue 21's speed goals, measured):
 * instruction counts of it2n_bspline_eval and it2n_bspline_solve against a
 * baseline written plainly in float (the same not-a-knot spline: Thomas
 * with a division per step, the textbook basis, 16 multiply-adds per net),
 * on survey-like grids of 4x4 to 32x32 points, type-1 and type-2 with z.
 * qemu -icount shift=0 (counter.h). Prints one line per figure and checks
 * that the baseline computes the same surfaces (within 1e-4 of the range),
 * so a ratio compares like with like. `make bench-bspline-mcu`.
 */
#include <stdint.h>
#include <string.h>

#include "counter.h"
#include "it2n.h"
#include "semihost.h"

int bench_main(void);

#define PTS_MAX 32u
#define NETS_MAX (IT2N_FP_COUNT * IT2N_CH_COUNT)
#define QUERIES 32u

static it2n_bspline_rec rec[IT2N_BSPLINE_DATA_RECS(PTS_MAX - 1u, PTS_MAX - 1u, IT2N_F_Z)];
static int32_t coef[IT2N_BSPLINE_MODEL_WORDS(PTS_MAX - 1u, PTS_MAX - 1u, IT2N_F_Z)];
static it2n_bspline_data ds;
static it2n_bspline_model mdl;
static it2n_point pt;

/* the float baseline: data [net][i][j], coefficients [net][r][s] */
static float fdata[NETS_MAX][PTS_MAX][PTS_MAX];
static float fcoef[NETS_MAX][PTS_MAX + 2u][PTS_MAX + 2u];
static float fout[NETS_MAX];
static float fline_buf[PTS_MAX + 2u];

/* ---- text ------------------------------------------------------------- */

static char *put_u(char *p, uint64_t v)
{
    char t[24];
    unsigned n = 0;
    do {
        t[n++] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u);
    while (n > 0u) {
        *p++ = t[--n];
    }
    return p;
}

static char *put_s(char *p, const char *s)
{
    while (*s != '\0') {
        *p++ = *s++;
    }
    return p;
}

/* ratio a/b with three decimals */
static char *put_ratio(char *p, uint64_t a, uint64_t b)
{
    uint64_t r = b ? (a * 1000u + b / 2u) / b : 0u;
    p = put_u(p, r / 1000u);
    *p++ = '.';
    *p++ = (char)('0' + (char)(r / 100u % 10u));
    *p++ = (char)('0' + (char)(r / 10u % 10u));
    *p++ = (char)('0' + (char)(r % 10u));
    return p;
}

/* ---- data --------------------------------------------------------------- */

static unsigned nets_of(unsigned flags)
{
    return IT2N_BSPLINE_NFP(flags) * IT2N_CH_COUNT;
}

/* The grid of bench_bspline.c: 10-unit lattice, a smooth depth, pseudo-
 * random memberships, nested footprints; into the core and the baseline. */
static int build(unsigned pts, unsigned flags)
{
    unsigned n = pts - 1u, i, j, fp;
    uint32_t s = 12345u;
    if (it2n_bspline_data_init(&ds, rec, sizeof rec / sizeof rec[0], n, n, flags, NULL) !=
        IT2N_OK) {
        return -1;
    }
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= n; j++) {
            it2n_val t;
            s = s * 1664525u + 1013904223u;
            t = (it2n_val)(s >> 9) + IT2N_VAL_ONE / 8;
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val off = ((it2n_val)fp - 3) * (IT2N_VAL_ONE / 4);
                it2n_val v[IT2N_CH_COUNT];
                unsigned slot = (flags & IT2N_F_TYPE1) ? 0u : fp, ch;
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                    continue;
                }
                v[0] = (it2n_val)(10u * i) * IT2N_VAL_ONE + off;
                v[1] = (it2n_val)(10u * j) * IT2N_VAL_ONE + off;
                v[2] = -(it2n_val)((i * 7u + j * 3u) % 50u) * IT2N_VAL_ONE / 4 + off;
                v[3] = t;
                v[4] = IT2N_VAL_ONE / 4;
                v[5] = IT2N_VAL_ONE / 8 + (it2n_val)fp * (IT2N_VAL_ONE / 64);
                if (it2n_bspline_data_put(&ds, i, j, fp, v, false, NULL) != IT2N_OK) {
                    return -1;
                }
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    fdata[slot * IT2N_CH_COUNT + ch][i][j] =
                        (float)v[ch] * (1.0f / 16777216.0f);
                }
            }
        }
    }
    it2n_bspline_model_init(&mdl, coef, sizeof coef / sizeof coef[0]);
    return 0;
}

/* ---- float baseline ------------------------------------------------------ */

/* v[1..N+1] = data in, v[0..N+2] = coefficients c_{-1}..c_{N+1} out. */
static void fline(float *v, unsigned N)
{
    float y0 = v[1], y1 = v[2], y2, d;
    unsigned k;
    if (N == 1u) {
        v[0] = 2.0f * y0 - y1;
        v[3] = 2.0f * y1 - y0;
        return;
    }
    y2 = v[3];
    if (N == 2u) {
        float c = (y0 - 2.0f * y1 + y2) / 6.0f;
        v[0] = 3.0f * y0 - 3.0f * y1 + y2 - c;
        v[1] = y0 - c;
        v[2] = y1 - c;
        v[3] = y2 - c;
        v[4] = y0 - 3.0f * y1 + 3.0f * y2 - c;
        return;
    }
    {
        float ya = v[N - 1u], yb = v[N], yc = v[N + 1u];
        float c1 = (8.0f * y1 - y0 - y2) / 6.0f, cn1 = (8.0f * yb - ya - yc) / 6.0f;
        float piv[PTS_MAX];
        unsigned M = N - 3u;
        /* Thomas on c_{k-1} + 4 c_k + c_{k+1} = 6 y_k, k = 2..N-2 */
        for (k = 0; k < M; k++) {
            float r = 6.0f * v[k + 3u];
            if (k == 0u) {
                r -= c1;
                d = 4.0f;
            } else {
                r -= v[k + 2u] / piv[k - 1u];
                d = 4.0f - 1.0f / piv[k - 1u];
            }
            if (k + 1u == M) {
                r -= cn1;
            }
            piv[k] = d;
            v[k + 3u] = r;
        }
        for (k = M; k-- > 0u;) {
            float r = v[k + 3u];
            if (k + 1u < M) {
                r -= v[k + 4u];
            }
            v[k + 3u] = r / piv[k];
        }
        v[2] = c1;
        v[N] = cn1;
        v[1] = 2.0f * (y0 + y1 + y2) / 3.0f - v[3];
        v[0] = 6.0f * y0 - 4.0f * v[1] - c1;
        v[N + 1u] = 2.0f * (yc + yb + ya) / 3.0f - v[N - 1u];
        v[N + 2u] = 6.0f * yc - 4.0f * v[N + 1u] - cn1;
    }
}

static void fsolve(unsigned pts, unsigned nets)
{
    unsigned n = pts - 1u, net, i, j;
    for (net = 0; net < nets; net++) {
        for (i = 0; i <= n; i++) { /* rows into fcoef rows 1..n+1 */
            for (j = 0; j <= n; j++) {
                fline_buf[j + 1u] = fdata[net][i][j];
            }
            fline(fline_buf, n);
            for (j = 0; j < n + 3u; j++) {
                fcoef[net][i + 1u][j] = fline_buf[j];
            }
        }
        for (j = 0; j < n + 3u; j++) { /* columns */
            for (i = 0; i <= n; i++) {
                fline_buf[i + 1u] = fcoef[net][i + 1u][j];
            }
            fline(fline_buf, n);
            for (i = 0; i < n + 3u; i++) {
                fcoef[net][i][j] = fline_buf[i];
            }
        }
    }
}

static void fbasis(float t, float b[4])
{
    float s = 1.0f - t;
    b[0] = s * s * s / 6.0f;
    b[1] = (3.0f * t * t * t - 6.0f * t * t + 4.0f) / 6.0f;
    b[2] = (-3.0f * t * t * t + 3.0f * t * t + 3.0f * t + 1.0f) / 6.0f;
    b[3] = t * t * t / 6.0f;
}

static void fquery(unsigned pts, unsigned nets, float u, float w)
{
    unsigned n = pts - 1u, k, l, net, a, b;
    float bu[4], bw[4], x = u * (float)n, y = w * (float)n;
    k = (unsigned)x;
    l = (unsigned)y;
    k = k > n - 1u ? n - 1u : k;
    l = l > n - 1u ? n - 1u : l;
    fbasis(x - (float)k, bu);
    fbasis(y - (float)l, bw);
    for (net = 0; net < nets; net++) {
        float sum = 0.0f;
        for (a = 0; a < 4u; a++) {
            float q = 0.0f;
            for (b = 0; b < 4u; b++) {
                q += bw[b] * fcoef[net][k + a][l + b];
            }
            sum += bu[a] * q;
        }
        fout[net] = sum;
    }
}

/* ---- the runs ------------------------------------------------------------ */

static int run_case(unsigned pts, unsigned flags, const char *name)
{
    char line[200], *p;
    uint32_t t0, t1;
    uint64_t solve_it, solve_f, q_it = 0, q_f = 0;
    unsigned nets = nets_of(flags), k;
    uint32_t s = 777u;
    int bad = 0;
    if (build(pts, flags) != 0) {
        return -1;
    }
    t0 = bc_now();
    bad |= it2n_bspline_solve(&mdl, &ds, NULL);
    t1 = bc_now();
    solve_it = bc_instr(t0, t1);
    t0 = bc_now();
    fsolve(pts, nets);
    t1 = bc_now();
    solve_f = bc_instr(t0, t1);
    for (k = 0; k < QUERIES; k++) {
        it2n_par u, w;
        float uf, wf;
        unsigned fp;
        s = s * 1664525u + 1013904223u;
        u = (it2n_par)(s >> 8) << 8;
        s = s * 1664525u + 1013904223u;
        w = (it2n_par)(s >> 8) << 8;
        uf = (float)u * (1.0f / 4294967296.0f);
        wf = (float)w * (1.0f / 4294967296.0f);
        t0 = bc_now();
        bad |= it2n_bspline_eval(&mdl, u, w, &pt, NULL);
        t1 = bc_now();
        q_it += bc_instr(t0, t1);
        t0 = bc_now();
        fquery(pts, nets, uf, wf);
        t1 = bc_now();
        q_f += bc_instr(t0, t1);
        /* the baseline computes the same surfaces */
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            unsigned slot = (flags & IT2N_F_TYPE1) ? 0u : fp, ch;
            if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                continue;
            }
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                float a = (float)pt.v[fp][ch] * (1.0f / 16777216.0f);
                float d = a - fout[slot * IT2N_CH_COUNT + ch];
                float range = ch < 3u ? 10.0f * (float)pts : 1.0f;
                if (d > 1e-4f * range || d < -1e-4f * range) {
                    bad = 1;
                }
            }
        }
    }
    p = put_s(line, "R bspline.");
    p = put_s(p, name);
    p = put_s(p, " solve it2n ");
    p = put_u(p, solve_it);
    p = put_s(p, " float ");
    p = put_u(p, solve_f);
    p = put_s(p, " ratio ");
    p = put_ratio(p, solve_it, solve_f);
    p = put_s(p, "; query it2n ");
    p = put_u(p, q_it / QUERIES);
    p = put_s(p, " float ");
    p = put_u(p, q_f / QUERIES);
    p = put_s(p, " ratio ");
    p = put_ratio(p, q_it, q_f);
    p = put_s(p, bad ? " MISMATCH\n" : "\n");
    *p = '\0';
    it2n_sh_write0(line);
    return bad ? -1 : 0;
}

int bench_main(void)
{
    uint64_t want, got;
    int bad = 0;
    bc_counter_start();
    if (bc_counter_validate(&want, &got) != 0) {
        it2n_sh_write0("FAIL: instruction counter\n");
        return 1;
    }
#if defined(__ARM_ARCH_6M__)
    it2n_sh_write0("B-spline kind, Cortex-M0+ code (-Os), instructions; float = soft float\n");
#else
    it2n_sh_write0("B-spline kind, Cortex-M4F code (-O2), instructions; float = FPU\n");
#endif
    bad |= run_case(4, IT2N_F_TYPE1 | IT2N_F_Z, "4x4_type1_xyz");
    bad |= run_case(32, IT2N_F_TYPE1 | IT2N_F_Z, "32x32_type1_xyz");
    bad |= run_case(4, IT2N_F_Z, "4x4_type2_xyz");
    bad |= run_case(16, IT2N_F_Z, "16x16_type2_xyz");
    bad |= run_case(32, IT2N_F_Z, "32x32_type2_xyz");
    it2n_sh_write0(bad ? "FAIL: bspline image\n" : "PASS: bspline image\n");
    return bad ? 1 : 0;
}
