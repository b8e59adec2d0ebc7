/*
 * B-spline kind on emulated Cortex-M (issue 21's speed and memory goals,
 * measured): instruction counts of it2n_bspline_eval and it2n_bspline_solve
 * against a baseline written plainly in float (the same not-a-knot spline:
 * Thomas with a division per step, the textbook basis, 16 multiply-adds per
 * net), on survey-like grids of 4x4 to 32x32 points, type-1 and type-2 with
 * z, for every magnitude the data set accepts: coordinates on a 10-unit
 * lattice, within +-1000, near +-IT2N_COORD_LIMIT, and a rough set (random
 * coordinates around the lattice, random memberships). Also the query count
 * at 4x4 and 256x256 points (type-1 x, y: a query reads a 4x4 window) and
 * the storage of model + data set per grid point. qemu -icount shift=0
 * (counter.h). Prints "R key value..." lines (per-point query counts, for
 * the paired intervals of tests/bench/mcu/bspline_results.py) and checks
 * that the baseline computes the same surfaces (within 1e-4 of the data's
 * range), so a ratio compares like with like. `make bench-bspline-mcu`.
 */
#include <stdint.h>
#include <string.h>

#include "baseline.h"
#include "counter.h"
#include "it2n.h"
#include "semihost.h"

int bench_main(void);

#define PTS_MAX 32u
#define BIG_PTS 256u /* the grid-independence case: type-1 x, y */
#define NETS_MAX (IT2N_FP_COUNT * IT2N_CH_COUNT)
#define QUERIES 32u
#define MAXOF(a, b) ((a) > (b) ? (a) : (b))
#define REC_CAP MAXOF(IT2N_BSPLINE_DATA_RECS(PTS_MAX - 1u, PTS_MAX - 1u, IT2N_F_Z), \
                      IT2N_BSPLINE_DATA_RECS(BIG_PTS - 1u, BIG_PTS - 1u, IT2N_F_TYPE1))
#define COEF_CAP MAXOF(IT2N_BSPLINE_MODEL_WORDS(PTS_MAX - 1u, PTS_MAX - 1u, IT2N_F_Z), \
                       IT2N_BSPLINE_MODEL_WORDS(BIG_PTS - 1u, BIG_PTS - 1u, IT2N_F_TYPE1))

static it2n_bspline_rec rec[REC_CAP];
static int32_t coef[COEF_CAP];
static it2n_bspline_data ds;
static it2n_bspline_model mdl;
static it2n_point pt;

/* the float baseline: data [net][i][j], coefficients [net][r][s] */
static float fdata[NETS_MAX][PTS_MAX][PTS_MAX];
static float fcoef[NETS_MAX][PTS_MAX + 2u][PTS_MAX + 2u];
static float fout[NETS_MAX];
static float fline_buf[PTS_MAX + 2u];

/* per-point query counts of the current case */
static uint32_t q_it[QUERIES], q_fl[QUERIES];

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

/* "R bs.<key>.<what> v1 v2 ..." */
static void put_list(const char *key, const char *what, const uint32_t *v, unsigned count)
{
    char line[24 * QUERIES + 80], *p = line;
    unsigned k;
    p = put_s(p, "R bs.");
    p = put_s(p, key);
    p = put_s(p, what);
    for (k = 0; k < count; k++) {
        *p++ = ' ';
        p = put_u(p, v[k]);
    }
    *p++ = '\n';
    *p = '\0';
    it2n_sh_write0(line);
}

/* ---- data --------------------------------------------------------------- */

enum { SET_LATTICE, SET_K1000, SET_LIMIT, SET_ROUGH, NSETS };
static const char *const set_name[NSETS] = {"lattice", "pm1000", "limit", "rough"};

static unsigned nets_of(unsigned flags)
{
    return IT2N_BSPLINE_NFP(flags) * IT2N_CH_COUNT;
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s;
}

/* -a + 2a k / n in Q24 (a in units, k <= n) */
static it2n_val spread(int64_t a, unsigned k, unsigned n)
{
    return ((2 * a * (int64_t)k) << IT2N_VAL_FRAC) / (int64_t)n - (a << IT2N_VAL_FRAC);
}

/* Coordinate ch of grid point (i, j) of set `set`, before the footprint's
 * offset (|offset| <= 0.75: every set stays within the limit). */
static it2n_val coord(unsigned set, unsigned ch, unsigned i, unsigned j, unsigned n,
                      uint32_t *s)
{
    const int64_t lim = IT2N_COORD_LIMIT - 1;
    unsigned depth = (i * 7u + j * 3u) % 50u;
    switch (set) {
    case SET_K1000:
        return ch == 0u ? spread(1000, i, n) : ch == 1u ? spread(1000, j, n)
                                                        : -spread(1000, depth, 49u);
    case SET_LIMIT:
        return ch == 0u ? spread(lim, i, n) : ch == 1u ? spread(lim, j, n)
                                                       : -spread(lim, depth, 49u);
    case SET_ROUGH: {
        /* the lattice jittered by up to +-4 units, depth random in +-500 */
        it2n_val r = (it2n_val)(lcg(s) >> 8) - (IT2N_VAL_ONE / 2);
        return ch == 0u ? (it2n_val)(10u * i) * IT2N_VAL_ONE + 8 * r
             : ch == 1u ? (it2n_val)(10u * j) * IT2N_VAL_ONE + 8 * r
                        : 1000 * r;
    }
    default: /* the grid of bench_bspline.c */
        return ch == 0u ? (it2n_val)(10u * i) * IT2N_VAL_ONE
             : ch == 1u ? (it2n_val)(10u * j) * IT2N_VAL_ONE
                        : -(it2n_val)depth * IT2N_VAL_ONE / 4;
    }
}

/* A pts x pts grid of set `set` into the core and (with_float) the
 * baseline; *range = the largest |coordinate|. Nested footprints. */
static int build(unsigned pts, unsigned flags, unsigned set, int with_float, float *range)
{
    unsigned n = pts - 1u, i, j, fp;
    uint32_t s = 12345u;
    it2n_val maxc = 0;
    if (it2n_bspline_data_init(&ds, rec, sizeof rec / sizeof rec[0], n, n, flags, NULL) !=
        IT2N_OK) {
        return -1;
    }
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= n; j++) {
            it2n_val base[3], t;
            unsigned ch;
            for (ch = 0; ch < 3u; ch++) {
                base[ch] = coord(set, ch, i, j, n, &s);
            }
            t = (it2n_val)(lcg(&s) >> 9) + IT2N_VAL_ONE / 8;
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val off = ((it2n_val)fp - 3) * (IT2N_VAL_ONE / 4);
                it2n_val v[IT2N_CH_COUNT];
                unsigned slot = (flags & IT2N_F_TYPE1) ? 0u : fp;
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                    continue;
                }
                for (ch = 0; ch < 3u; ch++) {
                    v[ch] = base[ch] + off;
                    if (ch < 2u || (flags & IT2N_F_Z)) {
                        it2n_val a = v[ch] < 0 ? -v[ch] : v[ch];
                        maxc = a > maxc ? a : maxc;
                    }
                }
                if (set == SET_ROUGH) {
                    v[3] = (it2n_val)(lcg(&s) >> 8);
                    v[4] = (it2n_val)(lcg(&s) >> 8);
                    v[5] = (it2n_val)(lcg(&s) >> 8);
                } else {
                    v[3] = t;
                    v[4] = IT2N_VAL_ONE / 4;
                    v[5] = IT2N_VAL_ONE / 8 + (it2n_val)fp * (IT2N_VAL_ONE / 64);
                }
                if (it2n_bspline_data_put(&ds, i, j, fp, v, false, NULL) != IT2N_OK) {
                    return -1;
                }
                for (ch = 0; ch < IT2N_CH_COUNT && with_float; ch++) {
                    fdata[slot * IT2N_CH_COUNT + ch][i][j] =
                        (float)v[ch] * (1.0f / 16777216.0f);
                }
            }
        }
    }
    *range = (float)maxc * (1.0f / 16777216.0f);
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

/* The baseline's entry points are compiled on their own (noinline), so
 * their code does not depend on the benchmark around the call. */
__attribute__((noinline)) static void fsolve(unsigned pts, unsigned nets)
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

__attribute__((noinline)) static void fquery(unsigned pts, unsigned nets, float u, float w)
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

static void lcg_uw(uint32_t *s, it2n_par *u, it2n_par *w)
{
    *u = (it2n_par)(lcg(s) >> 8) << 8;
    *w = (it2n_par)(lcg(s) >> 8) << 8;
}

/* One grid, one magnitude set: the solve and QUERIES queries of it2n and of
 * the float baseline, per-point counts printed as
 *   R bs.<name>.<set>.solve IT2N FLOAT
 *   R bs.<name>.<set>.query.it2n C1..C32 / .query.float C1..C32 */
static int run_case(unsigned pts, unsigned flags, const char *name, unsigned set)
{
    char key[64], *p;
    uint32_t t0, t1, solve[2];
    unsigned nets = nets_of(flags), k;
    uint32_t s = 777u;
    float range;
    int bad = 0;
    if (build(pts, flags, set, 1, &range) != 0) {
        return -1;
    }
    t0 = bc_now();
    bad |= it2n_bspline_solve(&mdl, &ds, NULL);
    t1 = bc_now();
    solve[0] = (uint32_t)bc_instr(t0, t1);
    t0 = bc_now();
    fsolve(pts, nets);
    t1 = bc_now();
    solve[1] = (uint32_t)bc_instr(t0, t1);
    for (k = 0; k < QUERIES; k++) {
        it2n_par u, w;
        float uf, wf;
        unsigned fp;
        lcg_uw(&s, &u, &w);
        uf = (float)u * (1.0f / 4294967296.0f);
        wf = (float)w * (1.0f / 4294967296.0f);
        t0 = bc_now();
        bad |= it2n_bspline_eval(&mdl, u, w, &pt, NULL);
        t1 = bc_now();
        q_it[k] = (uint32_t)bc_instr(t0, t1);
        t0 = bc_now();
        fquery(pts, nets, uf, wf);
        t1 = bc_now();
        q_fl[k] = (uint32_t)bc_instr(t0, t1);
        /* the baseline computes the same surfaces */
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            unsigned slot = (flags & IT2N_F_TYPE1) ? 0u : fp, ch;
            if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                continue;
            }
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                float a = (float)pt.v[fp][ch] * (1.0f / 16777216.0f);
                float d = a - fout[slot * IT2N_CH_COUNT + ch];
                float r = ch < 3u ? range : 1.0f;
                if (d > 1e-4f * r || d < -1e-4f * r) {
                    bad = 1;
                }
            }
        }
    }
    p = put_s(key, name);
    p = put_s(p, ".");
    p = put_s(p, set_name[set]);
    *p = '\0';
    put_list(key, ".solve", solve, 2u);
    put_list(key, ".query.it2n", q_it, QUERIES);
    put_list(key, ".query.float", q_fl, QUERIES);
    if (bad) {
        it2n_sh_write0("MISMATCH: ");
        it2n_sh_write0(key);
        it2n_sh_write0("\n");
    }
    return bad ? -1 : 0;
}

/* The same QUERIES queries of a type-1 x, y model at pts x pts points (no
 * baseline): R bs.grid<pts>.query.it2n C1..C32. */
static int run_grid(unsigned pts)
{
    char key[16], *p;
    uint32_t t0, t1, s = 777u;
    unsigned k;
    float range;
    int bad = 0;
    if (build(pts, IT2N_F_TYPE1, SET_LATTICE, 0, &range) != 0 ||
        it2n_bspline_solve(&mdl, &ds, NULL) != IT2N_OK) {
        return -1;
    }
    for (k = 0; k < QUERIES; k++) {
        it2n_par u, w;
        lcg_uw(&s, &u, &w);
        t0 = bc_now();
        bad |= it2n_bspline_eval(&mdl, u, w, &pt, NULL);
        t1 = bc_now();
        q_it[k] = (uint32_t)bc_instr(t0, t1);
    }
    p = put_s(key, "grid");
    p = put_u(p, pts);
    *p = '\0';
    put_list(key, ".query.it2n", q_it, QUERIES);
    return bad ? -1 : 0;
}

/* Bytes of data set + model at 64x64 points and the largest square grids
 * within budgets of 24 KiB and 112 KiB (a 32 KiB M0+, a 128 KiB M4F, each
 * leaving RAM for stack and application): R bs.mem.<cfg> B64 N24 N112. */
static uint32_t mem_bytes(unsigned n, unsigned flags)
{
    return (uint32_t)(IT2N_BSPLINE_DATA_RECS(n, n, flags) * sizeof(it2n_bspline_rec) +
                      IT2N_BSPLINE_MODEL_WORDS(n, n, flags) * sizeof(int32_t));
}

static void run_mem(const char *cfg, unsigned flags)
{
    uint32_t v[3];
    unsigned n, b;
    v[0] = mem_bytes(63u, flags);
    for (b = 0; b < 2u; b++) {
        uint32_t budget = b == 0u ? 24u * 1024u : 112u * 1024u;
        v[1u + b] = 0u;
        for (n = 1u; n <= IT2N_BSPLINE_MAX_N && mem_bytes(n, flags) <= budget; n++) {
            v[1u + b] = n + 1u; /* points per side */
        }
    }
    put_list(cfg, "", v, 3u);
}

/* ---- Bezier solve at every magnitude (issue 21) --------------------------- */

/* The Bezier kind's degree-7 x 7 solve (8 x 8 points, 7 footprints, x, y,
 * T, I, F as tests/bench/mcu/driver.c) of each magnitude set against the
 * float baseline of baseline.h (Gauss-Jordan inverses, two products):
 *   R bs.bez7.<set>.solve IT2N FLOAT
 * checked to compute the same surface at a few points. */
static it2n_dataset bz_ds;
static it2n_model bz_mdl;
static blf_data bz_f;
static blf_model bz_fm;
static blf_point bz_fp;

static int run_bezier(unsigned set)
{
    static const unsigned bz_ch[5] = {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F};
    const unsigned n = 7u;
    char key[32], *p;
    uint32_t t0, t1, v[2], s = 4242u;
    it2n_val maxc = 0;
    unsigned i, j, fp, c, k;
    int bad = it2n_dataset_init(&bz_ds, n, n, 0u, NULL) != IT2N_OK;
    for (i = 0; i <= n && !bad; i++) {
        for (j = 0; j <= n && !bad; j++) {
            it2n_val base[2];
            base[0] = coord(set, 0u, i, j, n, &s);
            base[1] = coord(set, 1u, i, j, n, &s);
            for (fp = 0; fp < IT2N_FP_COUNT && !bad; fp++) {
                it2n_val off = ((it2n_val)fp - 3) * (IT2N_VAL_ONE / 4);
                it2n_val val[IT2N_CH_COUNT] = {0, 0, 0, 0, 0, 0};
                val[IT2N_CH_X] = base[0] + off;
                val[IT2N_CH_Y] = base[1] + off;
                for (c = 0; c < 3u; c++) {
                    val[IT2N_CH_T + c] = set == SET_ROUGH ? (it2n_val)(lcg(&s) >> 8)
                                                          : IT2N_VAL_ONE / 4 + (it2n_val)(i * 8u + j + c) * (IT2N_VAL_ONE / 256);
                }
                for (c = 0; c < 2u; c++) {
                    it2n_val a = val[c] < 0 ? -val[c] : val[c];
                    maxc = a > maxc ? a : maxc;
                }
                bad |= it2n_dataset_put(&bz_ds, i, j, fp, val, false, NULL) != IT2N_OK;
                for (c = 0; c < 5u; c++) {
                    bz_f[fp][c][i][j] = (float)val[bz_ch[c]] * (1.0f / 16777216.0f);
                }
            }
        }
    }
    it2n_model_init(&bz_mdl);
    t0 = bc_now();
    bad |= it2n_model_solve(&bz_mdl, &bz_ds, NULL) != IT2N_OK;
    t1 = bc_now();
    v[0] = (uint32_t)bc_instr(t0, t1);
    t0 = bc_now();
    bad |= blf_solve(&bz_fm, n, n, (const blf_data *)&bz_f) != 0;
    t1 = bc_now();
    v[1] = (uint32_t)bc_instr(t0, t1);
    for (k = 0; k < 4u && !bad; k++) {
        it2n_par u = (it2n_par)(lcg(&s) >> 8) << 8, w = (it2n_par)(lcg(&s) >> 8) << 8;
        float range = (float)maxc * (1.0f / 16777216.0f);
        bad |= it2n_eval(&bz_mdl, u, w, &pt, NULL) != IT2N_OK;
        blf_query(&bz_fm, (float)u * (1.0f / 4294967296.0f), (float)w * (1.0f / 4294967296.0f), &bz_fp);
        for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
            for (c = 0; c < 5u; c++) {
                float d = (float)pt.v[fp][bz_ch[c]] * (1.0f / 16777216.0f) - bz_fp.v[fp][c];
                float r = c < 2u ? range : 1.0f;
                if (d > 1e-4f * r || d < -1e-4f * r) {
                    bad = 1;
                }
            }
        }
    }
    p = put_s(key, "bez7.");
    p = put_s(p, set_name[set]);
    *p = '\0';
    put_list(key, ".solve", v, 2u);
    if (bad) {
        it2n_sh_write0("MISMATCH: ");
        it2n_sh_write0(key);
        it2n_sh_write0("\n");
    }
    return bad ? -1 : 0;
}

int bench_main(void)
{
    static const struct {
        unsigned pts, flags;
        const char *name;
    } cases[] = {
        {4, IT2N_F_TYPE1 | IT2N_F_Z, "t1xyz4"},  {32, IT2N_F_TYPE1 | IT2N_F_Z, "t1xyz32"},
        {4, IT2N_F_Z, "t2xyz4"},                 {16, IT2N_F_Z, "t2xyz16"},
        {32, IT2N_F_Z, "t2xyz32"},
    };
    uint64_t want, got;
    unsigned c, set;
    int bad = 0;
    bc_counter_start();
    if (bc_counter_validate(&want, &got) != 0) {
        it2n_sh_write0("FAIL: instruction counter\n");
        return 1;
    }
    {
        uint32_t v[2] = {(uint32_t)want, (uint32_t)got};
        put_list("counter", "", v, 2u);
    }
#if defined(__ARM_ARCH_6M__)
    it2n_sh_write0("B-spline kind, Cortex-M0+ code (-Os), instructions; float = soft float\n");
#else
    it2n_sh_write0("B-spline kind, Cortex-M4F code (-O2), instructions; float = FPU\n");
#endif
    for (c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        for (set = 0; set < NSETS; set++) {
            bad |= run_case(cases[c].pts, cases[c].flags, cases[c].name, set);
        }
    }
    for (set = 0; set < NSETS; set++) {
        bad |= run_bezier(set);
    }
    bad |= run_grid(4u);
    bad |= run_grid(BIG_PTS);
    run_mem("mem.t1xy", IT2N_F_TYPE1);
    run_mem("mem.t1xyz", IT2N_F_TYPE1 | IT2N_F_Z);
    run_mem("mem.t2xy", 0u);
    run_mem("mem.t2xyz", IT2N_F_Z);
    it2n_sh_write0(bad ? "FAIL: bspline image\n" : "PASS: bspline image\n");
    return bad ? 1 : 0;
}
