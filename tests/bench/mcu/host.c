/*
 * Host side of the MCU benchmark (x86-64, -O2): the same data sets, the it2n
 * core (through it2n_calls.c), the float and double baselines and the
 * long-double reference of tests/core/ref.c.
 *   bench_host check [smoke]   baselines agree with it2n (exit 1 if not);
 *                              worst errors of it2n, float and double against
 *                              the reference (eval on a grid, control nets);
 *                              hash of it2n's results at the hash points.
 *   bench_host time ROUNDS [quick]
 *                              ns per full query, it2n / double / float, in
 *                              interleaved rounds (tests/bench/mcu/
 *                              host_rounds.py reads them until precise).
 *   bench_host cg IMPL SET     BC_NPTS_MAX queries of IMPL (it2n, double,
 *                              float) on data set SET inside cg_queries(),
 *                              for valgrind --toggle-collect=cg_queries.
 * Output: "R key value" lines, as the images.
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "baseline.h"
#include "bench_set.h"
#include "it2n_calls.h"
#include "point_hash.h"
#include "points.h"
#include "ref.h"

static blf_data f_data;
static bld_data d_data;
static blf_model f_mdl;
static bld_model d_mdl;
static blf_point f_pt;
static bld_point d_pt;
static ref_model ref;
/* The same reference solved from the Q24 values the core was given: the
 * control-net goal is about the solve, and a degree-7 inverse amplifies the
 * data's own Q24 rounding (3e-8) by up to 4.4e4. */
static ref_model refq;

/* Reference channel of baseline channel c (x, y, T, I, F). */
static const unsigned ref_ch[BENCH_CH] = {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F};

static void fail(const char *what)
{
    fprintf(stderr, "bench_host: %s\n", what);
    exit(1);
}

static const bench_set *find_set(const char *name)
{
    for (unsigned s = 0; s < BENCH_NSETS; s++)
        if (strcmp(bench_sets[s].name, name) == 0)
            return &bench_sets[s];
    fail("unknown data set");
    return NULL;
}

/* Load and solve set s in it2n, both baselines and (if with_ref) the reference. */
static void setup(const bench_set *s, int with_ref)
{
    if (bc_load(s) != 0 || bc_solve() != 0)
        fail("it2n load/solve failed");
    memset(&ref, 0, sizeof ref);
    ref.n = s->n;
    ref.m = s->m;
    ref.flags = 0;
    memset(&refq, 0, sizeof refq);
    refq.n = s->n;
    refq.m = s->m;
    for (unsigned r = 0; r < s->nrows; r++) {
        const bench_row *row = &s->rows[r];
        for (unsigned c = 0; c < BENCH_CH; c++) {
            f_data[row->fp][c][row->i][row->j] = (float)row->d[c];
            d_data[row->fp][c][row->i][row->j] = row->d[c];
            ref.data[row->i][row->j][row->fp][ref_ch[c]] = s->ld[r][c];
            refq.data[row->i][row->j][row->fp][ref_ch[c]] =
                (long double)row->q24[c] / 16777216.0L;
        }
    }
    if (blf_solve(&f_mdl, s->n, s->m, (const blf_data *)&f_data) != 0 ||
        bld_solve(&d_mdl, s->n, s->m, (const bld_data *)&d_data) != 0)
        fail("baseline solve failed");
    if (with_ref && (ref_solve(&ref, 0) != 0 || ref_solve(&refq, 0) != 0))
        fail("reference solve failed");
}

static long double q24ld(int64_t q)
{
    return (long double)q / 16777216.0L;
}

static void upd(long double *worst, long double got, long double want)
{
    long double d = fabsl(got - want);
    if (d > *worst)
        *worst = d;
}

static void out(const char *set, const char *key, long double v)
{
    printf("R %s.%s %.6Le\n", set, key, v);
}

/* Worst errors (index 0 memberships, 1 coordinates) of it2n, float, double. */
typedef struct errs {
    long double it2n[2], flt[2], dbl[2]; /* vs reference   */
    long double dev_f[2], dev_d[2];      /* vs it2n        */
} errs;

static void eval_at(errs *e, uint32_t u16, uint32_t w16)
{
    long double r[REF_FP][REF_CH];
    long double u = (long double)u16 / 65536.0L, w = (long double)w16 / 65536.0L;
    if (bc_query((int64_t)u16 << 16, (int64_t)w16 << 16) != 0)
        fail("it2n eval failed");
    blf_query(&f_mdl, (float)u16 / 65536.0f, (float)w16 / 65536.0f, &f_pt);
    bld_query(&d_mdl, (double)u16 / 65536.0, (double)w16 / 65536.0, &d_pt);
    ref_eval(&ref, u, w, r);
    for (unsigned fp = 0; fp < BL_FP; fp++)
        for (unsigned c = 0; c < BENCH_CH; c++) {
            unsigned k = c < 2 ? 1 : 0;
            long double want = r[fp][ref_ch[c]], it = q24ld(bc_value(fp, c));
            upd(&e->it2n[k], it, want);
            upd(&e->flt[k], (long double)f_pt.v[fp][c], want);
            upd(&e->dbl[k], (long double)d_pt.v[fp][c], want);
            upd(&e->dev_f[k], (long double)f_pt.v[fp][c], it);
            upd(&e->dev_d[k], (long double)d_pt.v[fp][c], it);
        }
}

static int check(int smoke)
{
    int bad = 0;
    for (unsigned s = 0; s < BENCH_NSETS; s++) {
        const bench_set *set = &bench_sets[s];
        errs e;
        unsigned grid = smoke ? 8 : 32;
        long double maxc = 0.0L, cg = 0.0L, ci[2] = {0, 0}, cf[2] = {0, 0}, cd[2] = {0, 0}, cx[2] = {0, 0};
        uint64_t h = BC_FNV_OFFSET;
        memset(&e, 0, sizeof e);
        setup(set, 1);
        for (unsigned r = 0; r < set->nrows; r++)
            for (unsigned c = 0; c < 2; c++)
                if (fabsl(set->ld[r][c]) > maxc)
                    maxc = fabsl(set->ld[r][c]);
        /* Evaluation: a (grid+1)^2 grid and the benchmark's points. */
        for (unsigned a = 0; a <= grid; a++)
            for (unsigned b = 0; b <= grid; b++)
                eval_at(&e, a * 65536u / grid, b * 65536u / grid);
        for (unsigned k = 0; k < BC_NPTS_MAX; k++) {
            uint32_t u16, w16;
            bc_point(k, &u16, &w16);
            eval_at(&e, u16, w16);
        }
        for (unsigned k = 0; k < BC_NPTS_HASH; k++) {
            uint32_t u16, w16;
            bc_point(k, &u16, &w16);
            if (bc_query((int64_t)u16 << 16, (int64_t)w16 << 16) != 0)
                fail("it2n eval failed");
            h = bc_hash_last_query(h);
        }
        /* Control nets; the goal is per channel: err <= 1e-6 max|P| + 1e-7. */
        for (unsigned fp = 0; fp < BL_FP; fp++)
            for (unsigned c = 0; c < BENCH_CH; c++) {
                long double mx = 0.0L, worst = 0.0L;
                unsigned k = c < 2 ? 1 : 0;
                for (unsigned i = 0; i <= set->n; i++)
                    for (unsigned j = 0; j <= set->m; j++) {
                        long double want = ref.ctrl[i][j][fp][ref_ch[c]];
                        long double wantq = refq.ctrl[i][j][fp][ref_ch[c]];
                        long double it = q24ld(bc_ctrl(i, j, fp, c));
                        if (fabsl(wantq) > mx)
                            mx = fabsl(wantq);
                        upd(&worst, it, wantq);
                        upd(&ci[k], it, wantq);
                        upd(&cx[k], it, want);
                        upd(&cf[k], (long double)f_mdl.p[fp][c][i][j], want);
                        upd(&cd[k], (long double)d_mdl.p[fp][c][i][j], want);
                    }
                if (worst / (1e-6L * mx + 1e-7L) > cg)
                    cg = worst / (1e-6L * mx + 1e-7L);
            }
        out(set->name, "max_abs_coord", maxc);
        out(set->name, "it2n.err_memb", e.it2n[0]);
        out(set->name, "it2n.err_coord", e.it2n[1]);
        out(set->name, "float.err_memb", e.flt[0]);
        out(set->name, "float.err_coord", e.flt[1]);
        out(set->name, "double.err_memb", e.dbl[0]);
        out(set->name, "double.err_coord", e.dbl[1]);
        out(set->name, "it2n.ctrl_err_memb", ci[0]);
        out(set->name, "it2n.ctrl_err_coord", ci[1]);
        out(set->name, "it2n.ctrl_goal_ratio", cg);
        out(set->name, "it2n.ctrl_err_memb_vs_decimal", cx[0]);
        out(set->name, "it2n.ctrl_err_coord_vs_decimal", cx[1]);
        out(set->name, "float.ctrl_err_memb", cf[0]);
        out(set->name, "float.ctrl_err_coord", cf[1]);
        out(set->name, "double.ctrl_err_memb", cd[0]);
        out(set->name, "double.ctrl_err_coord", cd[1]);
        out(set->name, "float.dev_memb", e.dev_f[0]);
        out(set->name, "float.dev_coord", e.dev_f[1]);
        out(set->name, "double.dev_memb", e.dev_d[0]);
        out(set->name, "double.dev_coord", e.dev_d[1]);
        printf("R %s.it2n.hash %llu\n", set->name, (unsigned long long)h);
        /* The baselines must compute the same surfaces as it2n. */
        if (e.dev_d[0] > 1e-6L || e.dev_d[1] > 1e-6L * (1.0L + maxc) ||
            e.dev_f[0] > 1e-4L || e.dev_f[1] > 1e-4L * (1.0L + maxc)) {
            fprintf(stderr, "bench_host: %s: baselines disagree with it2n "
                    "(float %.3Le / %.3Le, double %.3Le / %.3Le)\n", set->name,
                    e.dev_f[0], e.dev_f[1], e.dev_d[0], e.dev_d[1]);
            bad = 1;
        }
    }
    printf("R host.points %u\n", BC_NPTS_MAX); /* queries per cg_queries() */
    printf(bad ? "FAIL: bench_host check\n" : "PASS: bench_host check\n");
    return bad;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static uint32_t pu[BC_NPTS_MAX], pw[BC_NPTS_MAX];
static double pud[BC_NPTS_MAX], pwd[BC_NPTS_MAX];
static float puf[BC_NPTS_MAX], pwf[BC_NPTS_MAX];
static volatile double sink;

/* One pass over the points with implementation impl (0 it2n, 1 double, 2 float). */
static void points(void)
{
    for (unsigned k = 0; k < BC_NPTS_MAX; k++) {
        bc_point(k, &pu[k], &pw[k]);
        pud[k] = (double)pu[k] / 65536.0;
        pwd[k] = (double)pw[k] / 65536.0;
        puf[k] = (float)pu[k] / 65536.0f;
        pwf[k] = (float)pw[k] / 65536.0f;
    }
}

static void pass(int impl)
{
    for (unsigned k = 0; k < BC_NPTS_MAX; k++) {
        if (impl == 0) {
            (void)bc_query((int64_t)pu[k] << 16, (int64_t)pw[k] << 16);
        } else if (impl == 1) {
            bld_query(&d_mdl, pud[k], pwd[k], &d_pt);
            sink = d_pt.v[3][2];
        } else {
            blf_query(&f_mdl, puf[k], pwf[k], &f_pt);
            sink = (double)f_pt.v[3][2];
        }
    }
}

/* Interleaved rounds, up to max_rounds (the caller, host_rounds.py, stops
 * reading once every ratio's interval is narrow enough and ends the
 * process): per round and data set, one timed run of each implementation,
 * the order alternating with the round, so all see the same drift of the
 * machine's load. "R x86.sets N", then a line per round and set, flushed:
 *   R x86.round.SET it2n_ns double_ns float_ns */
static int timing(int quick, int max_rounds)
{
    double budget = quick ? 0.01 : 0.05; /* seconds per run and implementation */
    long reps[BENCH_NSETS][3];
    points();
    for (unsigned s = 0; s < BENCH_NSETS; s++) {
        setup(&bench_sets[s], 0);
        for (int impl = 0; impl < 3; impl++) {
            double t0 = now();
            reps[s][impl] = 0;
            while (now() - t0 < budget) {
                pass(impl);
                reps[s][impl]++;
            }
        }
    }
    printf("R x86.sets %u\n", (unsigned)BENCH_NSETS);
    for (int r = 0; r < max_rounds; r++)
        for (unsigned s = 0; s < BENCH_NSETS; s++) {
            double per[3];
            setup(&bench_sets[s], 0);
            for (int k = 0; k < 3; k++) {
                int impl = r % 2 == 0 ? k : 2 - k;
                double a = now(), b;
                for (long i = 0; i < reps[s][impl]; i++)
                    pass(impl);
                b = now();
                per[impl] = (b - a) / (double)(reps[s][impl] * (long)BC_NPTS_MAX);
            }
            printf("R x86.round.%s", bench_sets[s].name);
            for (int impl = 0; impl < 3; impl++)
                printf(" %.3f", per[impl] * 1e9);
            printf("\n");
            if (fflush(stdout) != 0)
                return 1;
        }
    return 0;
}

void cg_queries(int impl);
__attribute__((noinline)) void cg_queries(int impl)
{
    pass(impl);
}

int main(int argc, char **argv)
{
    if (argc >= 2 && strcmp(argv[1], "check") == 0)
        return check(argc >= 3 && strcmp(argv[2], "smoke") == 0);
    if (argc >= 3 && strcmp(argv[1], "time") == 0)
        return timing(argc >= 4 && strcmp(argv[3], "quick") == 0, atoi(argv[2]));
    if (argc == 4 && strcmp(argv[1], "cg") == 0) {
        int impl = strcmp(argv[2], "it2n") == 0 ? 0 : strcmp(argv[2], "double") == 0 ? 1 : 2;
        points();
        setup(find_set(argv[3]), 0);
        cg_queries(impl);
        return 0;
    }
    fprintf(stderr, "usage: bench_host check [smoke] | time ROUNDS [quick] | cg it2n|double|float SET\n");
    return 2;
}
