/*
 * Benchmark image (qemu mps2-an385: ARMv6-M code; mps2-an386: ARMv7E-M+FPU
 * code), run with -icount shift=0. For each data set (bench_sets) it solves
 * and queries with the it2n core (through it2n_calls.c only) and with the
 * float and double baselines, and prints instruction counts, stack use, the
 * baselines' deviation from it2n and a hash of it2n's results as "R" lines
 * (report.h). Mode from the semihosting command line: "quick" (16 points,
 * 2 repetitions), "smoke" (4 points, 1), default 32 points, 4 repetitions.
 * Ends with "PASS: bench image" or "FAIL: ..." (exit status 1).
 */
#include <stdint.h>

#include "baseline.h"
#include "bench_set.h"
#include "counter.h"
#include "it2n_calls.h"
#include "point_hash.h"
#include "points.h"
#include "report.h"
#include "stack_probe.h"

int bench_main(void);

static blf_data f_data;
static bld_data d_data;
static blf_model f_mdl;
static bld_model d_mdl;
static blf_point f_pt;
static bld_point d_pt;
static uint64_t counts[BC_NPTS_MAX];

/* Arguments of the stack-probe thunks. */
static int64_t th_u, th_w;
static float th_uf, th_wf;
static double th_ud, th_wd;
static unsigned th_n, th_m;

static void th_it2n_query(void)
{
    (void)bc_query(th_u, th_w);
}

static void th_it2n_solve(void)
{
    (void)bc_solve();
}

static void th_float_query(void)
{
    blf_query(&f_mdl, th_uf, th_wf, &f_pt);
}

static void th_double_query(void)
{
    bld_query(&d_mdl, th_ud, th_wd, &d_pt);
}

static void th_float_solve(void)
{
    (void)blf_solve(&f_mdl, th_n, th_m, (const blf_data *)&f_data);
}

/* Stack of the call `caller` makes (see stack_probe.h); prints the figure
 * and, as key + "_exact", whether that call was found (else the figure
 * counts from fn's call). */
static void probe(const char *set, const char *key, void (*fn)(void), uintptr_t caller)
{
    int exact;
    uint32_t used = bc_stack_probe(fn, caller, &exact);
    bc_result(set, key, used);
    bc_puts("R ");
    bc_puts(set);
    bc_puts(key);
    bc_puts("_exact ");
    bc_put_u64((uint64_t)exact);
    bc_puts("\n");
}

static void load_baselines(const bench_set *s)
{
    unsigned r, c;
    for (r = 0; r < s->nrows; r++) {
        const bench_row *row = &s->rows[r];
        for (c = 0; c < BENCH_CH; c++) {
            f_data[row->fp][c][row->i][row->j] = (float)row->d[c];
            d_data[row->fp][c][row->i][row->j] = row->d[c];
        }
    }
}

static void print_counts(const char *set, const char *what, unsigned n)
{
    unsigned k;
    bc_puts("R ");
    bc_puts(set);
    bc_puts(what);
    for (k = 0; k < n; k++) {
        bc_puts(" ");
        bc_put_u64(counts[k]);
    }
    bc_puts("\n");
}

static double q24d(int64_t q)
{
    return (double)q * (1.0 / 16777216.0);
}

static void upd(double *worst, double got, double want)
{
    double d = got > want ? got - want : want - got;
    if (d > *worst) {
        *worst = d;
    }
}

static uint64_t e9(double x)
{
    return (uint64_t)(x * 1e9 + 0.5);
}

/* Deviation of the baselines from it2n (eval at the hash points and control
 * nets) and the hash of it2n's results. Returns -1 if an it2n call fails. */
static int compare(const bench_set *s)
{
    double fm = 0.0, fc = 0.0, dm = 0.0, dc = 0.0, fn = 0.0, dn = 0.0;
    uint64_t h = BC_FNV_OFFSET;
    unsigned k, fp, ch, i, j;
    for (k = 0; k < BC_NPTS_HASH; k++) {
        uint32_t u16, w16;
        bc_point(k, &u16, &w16);
        if (bc_query((int64_t)u16 << 16, (int64_t)w16 << 16) != 0) {
            return -1;
        }
        h = bc_hash_last_query(h);
        blf_query(&f_mdl, (float)u16 / 65536.0f, (float)w16 / 65536.0f, &f_pt);
        bld_query(&d_mdl, (double)u16 / 65536.0, (double)w16 / 65536.0, &d_pt);
        for (fp = 0; fp < BL_FP; fp++) {
            for (ch = 0; ch < BL_CH; ch++) {
                double ref = q24d(bc_value(fp, ch));
                upd(ch < 2u ? &fc : &fm, (double)f_pt.v[fp][ch], ref);
                upd(ch < 2u ? &dc : &dm, d_pt.v[fp][ch], ref);
            }
        }
        for (ch = 0; ch < 3u; ch++) {
            upd(&fm, (double)f_pt.upper_min[ch], q24d(bc_summary(0, ch)));
            upd(&fm, (double)f_pt.upper_max[ch], q24d(bc_summary(1, ch)));
            upd(&fm, (double)f_pt.lower_min[ch], q24d(bc_summary(2, ch)));
            upd(&fm, (double)f_pt.lower_max[ch], q24d(bc_summary(3, ch)));
            upd(&dm, d_pt.upper_min[ch], q24d(bc_summary(0, ch)));
            upd(&dm, d_pt.upper_max[ch], q24d(bc_summary(1, ch)));
            upd(&dm, d_pt.lower_min[ch], q24d(bc_summary(2, ch)));
            upd(&dm, d_pt.lower_max[ch], q24d(bc_summary(3, ch)));
        }
    }
    for (fp = 0; fp < BL_FP; fp++) {
        for (ch = 0; ch < BL_CH; ch++) {
            for (i = 0; i <= s->n; i++) {
                for (j = 0; j <= s->m; j++) {
                    double ref = q24d(bc_ctrl(i, j, fp, ch));
                    upd(&fn, (double)f_mdl.p[fp][ch][i][j], ref);
                    upd(&dn, d_mdl.p[fp][ch][i][j], ref);
                }
            }
        }
    }
    bc_result(s->name, ".float.dev_memb_e9", e9(fm));
    bc_result(s->name, ".float.dev_coord_e9", e9(fc));
    bc_result(s->name, ".float.dev_ctrl_e9", e9(fn));
    bc_result(s->name, ".double.dev_memb_e9", e9(dm));
    bc_result(s->name, ".double.dev_coord_e9", e9(dc));
    bc_result(s->name, ".double.dev_ctrl_e9", e9(dn));
    bc_result(s->name, ".it2n.hash", h);
    return 0;
}

static int run_set(const bench_set *s, unsigned npts, unsigned reps)
{
    uint32_t t0, t1;
    unsigned k, r;
    int rc;
    load_baselines(s);
    if (bc_load(s) != 0) {
        bc_puts("FAIL: it2n data set load\n");
        return -1;
    }
    /* Solve: one call each. */
    t0 = bc_now();
    rc = bc_solve();
    t1 = bc_now();
    bc_result(s->name, ".it2n.solve", bc_instr(t0, t1));
    if (rc != 0) {
        bc_puts("FAIL: it2n solve\n");
        return -1;
    }
    t0 = bc_now();
    rc = blf_solve(&f_mdl, s->n, s->m, (const blf_data *)&f_data);
    t1 = bc_now();
    bc_result(s->name, ".float.solve", bc_instr(t0, t1));
    t0 = bc_now();
    rc |= bld_solve(&d_mdl, s->n, s->m, (const bld_data *)&d_data);
    t1 = bc_now();
    bc_result(s->name, ".double.solve", bc_instr(t0, t1));
    if (rc != 0) {
        bc_puts("FAIL: baseline solve (singular)\n");
        return -1;
    }
    if (compare(s) != 0) {
        bc_puts("FAIL: it2n query\n");
        return -1;
    }
    /* One full query per point, reps calls per reading. */
    for (k = 0; k < npts; k++) {
        uint32_t u16, w16;
        int64_t u, w;
        bc_point(k, &u16, &w16);
        u = (int64_t)u16 << 16;
        w = (int64_t)w16 << 16;
        t0 = bc_now();
        for (r = 0; r < reps; r++) {
            (void)bc_query(u, w);
        }
        t1 = bc_now();
        counts[k] = bc_instr(t0, t1) / reps;
    }
    print_counts(s->name, ".it2n.query", npts);
    for (k = 0; k < npts; k++) {
        uint32_t u16, w16;
        float u, w;
        bc_point(k, &u16, &w16);
        u = (float)u16 / 65536.0f;
        w = (float)w16 / 65536.0f;
        t0 = bc_now();
        for (r = 0; r < reps; r++) {
            blf_query(&f_mdl, u, w, &f_pt);
        }
        t1 = bc_now();
        counts[k] = bc_instr(t0, t1) / reps;
    }
    print_counts(s->name, ".float.query", npts);
    for (k = 0; k < npts; k++) {
        uint32_t u16, w16;
        double u, w;
        bc_point(k, &u16, &w16);
        u = (double)u16 / 65536.0;
        w = (double)w16 / 65536.0;
        t0 = bc_now();
        for (r = 0; r < reps; r++) {
            bld_query(&d_mdl, u, w, &d_pt);
        }
        t1 = bc_now();
        counts[k] = bc_instr(t0, t1) / reps;
    }
    print_counts(s->name, ".double.query", npts);
    /* Stack, from the call, at an interior point. */
    th_u = (int64_t)21845 << 16;
    th_w = (int64_t)43690 << 16;
    th_uf = 21845.0f / 65536.0f;
    th_wf = 43690.0f / 65536.0f;
    th_ud = 21845.0 / 65536.0;
    th_wd = 43690.0 / 65536.0;
    th_n = s->n;
    th_m = s->m;
    probe(s->name, ".it2n.eval_stack", th_it2n_query, (uintptr_t)bc_query);
    probe(s->name, ".it2n.solve_stack", th_it2n_solve, (uintptr_t)bc_solve);
    probe(s->name, ".float.eval_stack", th_float_query, (uintptr_t)th_float_query);
    probe(s->name, ".double.eval_stack", th_double_query, (uintptr_t)th_double_query);
    probe(s->name, ".float.solve_stack", th_float_solve, (uintptr_t)th_float_solve);
    return 0;
}

int bench_main(void)
{
    static char cmd[128];
    unsigned npts = BC_NPTS_MAX, reps = 4u, s;
    uint64_t expected, measured;
    uint32_t t0, t1;
    int failed = 0;

#if defined(__ARM_ARCH_6M__)
    bc_puts("it2n bench image, ARMv6-M code (Cortex-M0+)\n");
#elif defined(__ARM_FP)
    bc_puts("it2n bench image, ARMv7E-M code with FPU (Cortex-M4F)\n");
#else
    bc_puts("it2n bench image, ARMv7-M code\n");
#endif
    bc_cmdline(cmd, sizeof cmd);
    if (bc_has_word(cmd, "smoke")) {
        npts = BC_NPTS_SMOKE;
        reps = 1u;
    } else if (bc_has_word(cmd, "quick")) {
        npts = BC_NPTS_QUICK;
        reps = 2u;
    }
    bc_result("points", "", npts);
    bc_result("reps", "", reps);
    bc_counter_start();
    t0 = bc_now();
    t1 = bc_now();
    bc_result("counter.overhead", "", bc_instr(t0, t1));
    if (bc_counter_validate(&expected, &measured) != 0) {
        bc_puts("FAIL: instruction counter off by more than 1 %\n");
        failed = 1;
    }
    bc_result("counter.expected", "", expected);
    bc_result("counter.measured", "", measured);
    for (s = 0; s < BENCH_NSETS; s++) {
        if (run_set(&bench_sets[s], npts, reps) != 0) {
            failed = 1;
        }
    }
    bc_puts(failed ? "FAIL: bench image\n" : "PASS: bench image\n");
    return failed;
}
