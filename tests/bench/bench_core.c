/*
 * Core benchmark (make bench): ratios measured in one run, so they hold on
 * any machine —
 *   full re-solve vs incremental it2n_model_update per changed point,
 *   it2n_sample R x C vs R*C calls of it2n_eval,
 *   solve time by degree.
 * Usage: bench_core [--smoke] [--ops]
 *   --smoke  ~1 s: tiny budgets; checks results (update bit-identical to a
 *            re-solve, sample bit-identical to eval), never wall-clock times.
 *   --ops    one of each operation, for valgrind --tool=callgrind counts.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "it2n.h"

static double budget = 0.25; /* seconds per timed measurement */

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void die(const char *what, int rc)
{
    fprintf(stderr, "bench_core: %s failed: %s (%d)\n", what, it2n_strerror(rc), rc);
    exit(1);
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

/* Nested seven-footprint grid on a jittered 10-unit lattice (as the vectors). */
static void make_grid(it2n_dataset *ds, unsigned n, unsigned m, uint32_t seed)
{
    it2n_errinfo err;
    int rc = it2n_dataset_init(ds, n, m, 0, &err);
    if (rc != IT2N_OK) die("dataset_init", rc);
    for (unsigned i = 0; i <= n; i++) {
        for (unsigned j = 0; j <= m; j++) {
            it2n_val jx = (it2n_val)(lcg(&seed) >> 2) - ((it2n_val)1 << 21);
            it2n_val jy = (it2n_val)(lcg(&seed) >> 2) - ((it2n_val)1 << 21);
            it2n_val t = IT2N_VAL_ONE / 20 + ((it2n_val)lcg(&seed) * 9) / 10;
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val off = ((it2n_val)fp - IT2N_FP_D) * (3 * IT2N_VAL_ONE / 2);
                it2n_val v[IT2N_CH_COUNT] = {
                    (it2n_val)(10 * i) * IT2N_VAL_ONE + jx + off,
                    (it2n_val)(10 * j) * IT2N_VAL_ONE + jy + off,
                    0, t, IT2N_VAL_ONE - t, t / 2,
                };
                rc = it2n_dataset_put(ds, i, j, fp, v, false, &err);
                if (rc != IT2N_OK) die("dataset_put", rc);
            }
        }
    }
}

/* The k-th point change: new memberships for one (i, j, fp). */
static void change(const it2n_dataset *ds, unsigned k, unsigned *i, unsigned *j,
                   unsigned *fp, it2n_val v[IT2N_CH_COUNT])
{
    *i = k % (ds->n + 1u);
    *j = (k / (ds->n + 1u)) % (ds->m + 1u);
    *fp = k % IT2N_FP_COUNT;
    it2n_dataset_get(ds, *i, *j, *fp, v);
    v[IT2N_CH_T] = (it2n_val)((k * 2654435761u) % (uint32_t)IT2N_VAL_ONE);
}

/* mdl_a is solved from (and updated with) ds_a; mdl_b from ds_b. */
static it2n_model mdl_a, mdl_b;
static it2n_dataset ds_a, ds_b;

/* Seconds per call of one update, and per full re-solve of the same change;
 * for one change applied both ways, the largest difference of a control
 * point (Q24 LSB) and whether the nets are bit-identical. */
static void time_update(unsigned deg, double *t_upd, double *t_solve, long *max_lsb,
                        bool *identical)
{
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    unsigned i, j, fp, k;
    int rc;
    double t0;
    long calls;

    make_grid(&ds_a, deg, deg, 42u + deg);
    it2n_model_init(&mdl_a);
    if ((rc = it2n_model_solve(&mdl_a, &ds_a, &err)) != IT2N_OK) die("solve", rc);

    calls = 0;
    t0 = now();
    do {
        change(&ds_a, (unsigned)calls, &i, &j, &fp, v);
        if ((rc = it2n_model_update(&mdl_a, &ds_a, i, j, fp, v, &err)) != IT2N_OK) die("update", rc);
        calls++;
    } while (now() - t0 < budget);
    *t_upd = (now() - t0) / (double)calls;

    calls = 0;
    ds_b = ds_a;
    t0 = now();
    do {
        change(&ds_b, (unsigned)calls, &i, &j, &fp, v);
        if ((rc = it2n_dataset_put(&ds_b, i, j, fp, v, true, &err)) != IT2N_OK) die("put", rc);
        if ((rc = it2n_model_solve(&mdl_b, &ds_b, &err)) != IT2N_OK) die("solve", rc);
        calls++;
    } while (now() - t0 < budget);
    *t_solve = (now() - t0) / (double)calls;

    /* One change applied both ways to a freshly solved model: how far
     * apart? (The core promises bit-identical, after any number of
     * updates; tests/core checks chains of them.) */
    k = 12345u;
    it2n_model_init(&mdl_a);
    if ((rc = it2n_model_solve(&mdl_a, &ds_a, &err)) != IT2N_OK) die("solve", rc);
    ds_b = ds_a;
    change(&ds_a, k, &i, &j, &fp, v);
    if ((rc = it2n_model_update(&mdl_a, &ds_a, i, j, fp, v, &err)) != IT2N_OK) die("update", rc);
    if ((rc = it2n_dataset_put(&ds_b, i, j, fp, v, true, &err)) != IT2N_OK) die("put", rc);
    it2n_model_init(&mdl_b);
    if ((rc = it2n_model_solve(&mdl_b, &ds_b, &err)) != IT2N_OK) die("solve", rc);
    *max_lsb = 0;
    for (i = 0; i <= deg; i++)
        for (j = 0; j <= deg; j++)
            for (fp = 0; fp < IT2N_FP_COUNT; fp++)
                for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    long d = labs((long)(it2n_model_ctrl(&mdl_a, i, j, fp, ch) -
                                         it2n_model_ctrl(&mdl_b, i, j, fp, ch)));
                    if (d > *max_lsb) *max_lsb = d;
                }
    *identical = memcmp(mdl_a.frac, mdl_b.frac, sizeof mdl_a.frac) == 0 &&
                 memcmp(mdl_a.net, mdl_b.net, sizeof mdl_a.net) == 0 &&
                 memcmp(&ds_a, &ds_b, sizeof ds_a) == 0;
}

/* Sample sink: checks each node against a direct it2n_eval. */
typedef struct sample_ctx {
    const it2n_model *mdl;
    bool verify;
    unsigned nodes, mismatches;
    it2n_val sink;
} sample_ctx;

static int sample_cb(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w,
                     const it2n_point *pt)
{
    sample_ctx *s = ctx;
    (void)r;
    (void)c;
    s->nodes++;
    s->sink += pt->v[IT2N_FP_D][IT2N_CH_T];
    if (s->verify) {
        it2n_point p;
        if (it2n_eval(s->mdl, u, w, &p, NULL) != IT2N_OK ||
            memcmp(p.v, pt->v, sizeof p.v) != 0 || p.out_of_range != pt->out_of_range) {
            s->mismatches++;
        }
    }
    return 0;
}

/* Seconds for one rows x cols it2n_sample, and for rows*cols it2n_eval. */
static void time_sample(unsigned rows, unsigned cols, double *t_sample, double *t_eval,
                        unsigned *mismatches)
{
    sample_ctx s = {&mdl_a, false, 0, 0, 0};
    it2n_point p;
    double t0;
    long calls;
    int rc;

    calls = 0;
    t0 = now();
    do {
        if ((rc = it2n_sample(&mdl_a, rows, cols, sample_cb, &s, NULL)) != IT2N_OK) die("sample", rc);
        calls++;
    } while (now() - t0 < budget);
    *t_sample = (now() - t0) / (double)calls;

    calls = 0;
    t0 = now();
    do {
        for (unsigned r = 0; r < rows; r++) {
            for (unsigned c = 0; c < cols; c++) {
                it2n_par u = (it2n_par)(((uint64_t)r << IT2N_PAR_FRAC) / (rows - 1u));
                it2n_par w = (it2n_par)(((uint64_t)c << IT2N_PAR_FRAC) / (cols - 1u));
                if ((rc = it2n_eval(&mdl_a, u, w, &p, NULL)) != IT2N_OK) die("eval", rc);
                s.sink += p.v[IT2N_FP_D][IT2N_CH_T];
            }
        }
        calls++;
    } while (now() - t0 < budget);
    *t_eval = (now() - t0) / (double)calls;

    s.verify = true;
    s.nodes = 0;
    if ((rc = it2n_sample(&mdl_a, rows, cols, sample_cb, &s, NULL)) != IT2N_OK) die("sample", rc);
    *mismatches = s.mismatches + (s.nodes != rows * cols);
}

static double time_solve(unsigned n, unsigned m)
{
    it2n_errinfo err;
    double t0;
    long calls = 0;
    int rc;
    make_grid(&ds_a, n, m, 7u * n + m);
    t0 = now();
    do {
        if ((rc = it2n_model_solve(&mdl_b, &ds_a, &err)) != IT2N_OK) die("solve", rc);
        calls++;
    } while (now() - t0 < budget);
    return (now() - t0) / (double)calls;
}

/* One of each operation at degree 7, for instruction counts. */
static int run_ops(void)
{
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    unsigned i, j, fp;
    sample_ctx s = {&mdl_a, false, 0, 0, 0};
    it2n_point p;
    int rc;
    make_grid(&ds_a, 7, 7, 49u);
    it2n_model_init(&mdl_a);
    if ((rc = it2n_model_solve(&mdl_a, &ds_a, &err)) != IT2N_OK) die("solve", rc);
    change(&ds_a, 3, &i, &j, &fp, v);
    if ((rc = it2n_model_update(&mdl_a, &ds_a, i, j, fp, v, &err)) != IT2N_OK) die("update", rc);
    if ((rc = it2n_sample(&mdl_a, 16, 16, sample_cb, &s, NULL)) != IT2N_OK) die("sample", rc);
    for (unsigned r = 0; r < 16u; r++)
        for (unsigned c = 0; c < 16u; c++)
            if ((rc = it2n_eval(&mdl_a, (it2n_par)(((uint64_t)r << 32) / 15u),
                                (it2n_par)(((uint64_t)c << 32) / 15u), &p, NULL)) != IT2N_OK)
                die("eval", rc);
    return 0;
}

int main(int argc, char **argv)
{
    bool smoke = argc > 1 && strcmp(argv[1], "--smoke") == 0;
    int failures = 0;
    double tu, ts, tsa, tev;
    long lsb;
    bool same;
    unsigned mism;

    if (argc > 1 && strcmp(argv[1], "--ops") == 0) {
        return run_ops();
    }
    if (smoke) {
        budget = 0.02;
    }
    printf("it2n core benchmark (%s; ratios from one run, times are this machine's)\n",
           smoke ? "smoke" : "full");

    printf("\nincremental update vs full re-solve, per changed point:\n");
    for (unsigned deg = 3; deg <= IT2N_MAX_DEGREE; deg += 4) {
        time_update(deg, &tu, &ts, &lsb, &same);
        printf("  %ux%u  update %9.2f us  re-solve %9.2f us  ratio %6.1fx  max diff %ld LSB%s\n",
               deg, deg, tu * 1e6, ts * 1e6, ts / tu, lsb, same ? " (bit-identical)" : "");
        if (!same) {
            printf("  FAIL: update is not bit-identical to a re-solve (max diff %ld LSB)\n", lsb);
            failures++;
        }
    }

    printf("\nit2n_sample RxC vs RxC calls of it2n_eval (degree %ux%u):\n",
           (unsigned)mdl_a.n, (unsigned)mdl_a.m);
    for (unsigned g = 8; g <= (smoke ? 8u : 64u); g *= 8) {
        time_sample(g, g, &tsa, &tev, &mism);
        printf("  %3ux%-3u sample %9.1f us  evals %9.1f us  ratio %5.2fx  %u mismatches\n",
               g, g, tsa * 1e6, tev * 1e6, tev / tsa, mism);
        if (mism) {
            printf("  FAIL: it2n_sample differs from it2n_eval at %u nodes\n", mism);
            failures++;
        }
    }

    printf("\nsolve time by degree (n = m), relative to 1x1:\n");
    double t1 = time_solve(1, 1);
    for (unsigned d = 1; d <= IT2N_MAX_DEGREE; d += (smoke ? 6u : 1u)) {
        double t = d == 1 ? t1 : time_solve(d, d);
        printf("  %ux%u  %9.2f us  %6.1fx\n", d, d, t * 1e6, t / t1);
    }
    printf("\n%s\n", failures ? "bench_core: FAILED" : "bench_core: ok");
    return failures ? 1 : 0;
}
