/*
 * B-spline kind benchmark (issue 21): host solve time by grid size and kind
 * (best of 3 wall-clock runs, printed, never asserted) and the workload for
 * the instruction counts of one query at 4x4 and at 256x256 points
 * (`make bench-bspline` runs it under callgrind: a query reads a 4x4 window,
 * so its instruction count must not grow with the grid).
 *   bench_bspline --time          solve and eval timings
 *   bench_bspline --rounds MAX    solve times in interleaved rounds, one line
 *                                 per round (tests/bench/mcu/bspline_rounds.py
 *                                 reads them until the intervals are tight)
 *   bench_bspline --eval N        build an N x N type-2 x,y,z model, then
 *                                 256 queries (what callgrind counts)
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "it2n.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

typedef struct bmodel {
    it2n_bspline_rec *rec;
    int32_t *coef;
    it2n_bspline_data ds;
    it2n_bspline_model mdl;
} bmodel;

/* A survey-like grid of `pts` x `pts` points: 10-unit lattice, a smooth
 * depth, memberships from a pseudo-random walk, footprints nested. */
static void build(bmodel *b, unsigned pts, unsigned flags)
{
    unsigned n = pts - 1u, i, j, fp;
    size_t recs = IT2N_BSPLINE_DATA_RECS(n, n, flags);
    size_t words = IT2N_BSPLINE_MODEL_WORDS(n, n, flags);
    uint32_t s = 12345u;
    b->rec = malloc(recs * sizeof(*b->rec));
    b->coef = malloc(words * sizeof(*b->coef));
    if (b->rec == NULL || b->coef == NULL ||
        it2n_bspline_data_init(&b->ds, b->rec, recs, n, n, flags, NULL) != IT2N_OK) {
        fprintf(stderr, "bench_bspline: setup failed\n");
        exit(1);
    }
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= n; j++) {
            it2n_val t;
            s = s * 1664525u + 1013904223u;
            t = (it2n_val)(s >> 9) + IT2N_VAL_ONE / 8; /* 0.125 .. 0.625 */
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val off = ((it2n_val)fp - 3) * (IT2N_VAL_ONE / 4);
                it2n_val v[IT2N_CH_COUNT];
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                    continue;
                }
                v[0] = (it2n_val)(10 * i) * IT2N_VAL_ONE + off;
                v[1] = (it2n_val)(10 * j) * IT2N_VAL_ONE + off;
                v[2] = -(it2n_val)((i * 7 + j * 3) % 50) * IT2N_VAL_ONE / 4 + off;
                v[3] = t;
                v[4] = IT2N_VAL_ONE / 4;
                v[5] = IT2N_VAL_ONE / 8 + (it2n_val)fp * (IT2N_VAL_ONE / 64);
                if (it2n_bspline_data_put(&b->ds, i, j, fp, v, false, NULL) != IT2N_OK) {
                    fprintf(stderr, "bench_bspline: put failed\n");
                    exit(1);
                }
            }
        }
    }
    it2n_bspline_model_init(&b->mdl, b->coef, words);
}

static void drop(bmodel *b)
{
    free(b->rec);
    free(b->coef);
}

static it2n_par lcg_par(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return (it2n_par)*s; /* [0, 1) in Q32 */
}

static int eval_many(const bmodel *b, unsigned count)
{
    it2n_point pt;
    uint32_t s = 99u;
    unsigned k;
    int bad = 0;
    for (k = 0; k < count; k++) {
        it2n_par u = lcg_par(&s), w = lcg_par(&s);
        bad |= it2n_bspline_eval(&b->mdl, u, w, &pt, NULL);
    }
    return bad;
}

static void time_one(unsigned pts, unsigned flags, const char *what)
{
    bmodel b;
    double best = 1e9, t0, q;
    int k;
    build(&b, pts, flags);
    for (k = 0; k < 3; k++) {
        t0 = now();
        if (it2n_bspline_solve(&b.mdl, &b.ds, NULL) != IT2N_OK) {
            fprintf(stderr, "bench_bspline: solve failed\n");
            exit(1);
        }
        t0 = now() - t0;
        best = t0 < best ? t0 : best;
    }
    t0 = now();
    (void)eval_many(&b, 100000u);
    q = (now() - t0) / 100000.0;
    printf("  %3ux%-3u %-13s solve %8.2f ms   query %6.0f ns (every footprint and channel)\n",
           pts, pts, what, best * 1e3, q * 1e9);
    drop(&b);
}

/* CPU time of this (single-threaded) process: the solve's own time, which
 * the wall clock of a shared machine is not. */
static double cpu_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* The cases timed in rounds, in the order of each round's line. */
#define ROUND_CASES 3
static const struct {
    unsigned pts, flags;
    const char *key;
} round_case[ROUND_CASES] = {
    {64, IT2N_F_Z, "t2xyz64"},
    {256, IT2N_F_TYPE1 | IT2N_F_Z, "t1xyz256"},
    {256, IT2N_F_Z, "t2xyz256"},
};

/* Up to `max` interleaved rounds, each solving every case once (in reverse
 * order on odd rounds, so neither side of a ratio always runs first on a
 * warm or cold cache), one line per round:
 *   R host.round <key> <wall ms> <cpu ms> ...  (cases in round_case order)
 * flushed at once: the reader stops the rounds when its intervals are
 * tight (a ratio of times from one run reads met or unmet with the other
 * jobs' load, issue 22). The target is on the CPU time; the wall clock
 * shows how much other jobs took. */
static int rounds(int max)
{
    static bmodel b[ROUND_CASES];
    double wall[ROUND_CASES], cpu[ROUND_CASES];
    int r, c, k;
    for (c = 0; c < ROUND_CASES; c++) {
        build(&b[c], round_case[c].pts, round_case[c].flags);
        /* untimed: the first solve into fresh memory pays its page faults
         * (a first round of 80 ms against 45 for the next ones) */
        if (it2n_bspline_solve(&b[c].mdl, &b[c].ds, NULL) != IT2N_OK) {
            fprintf(stderr, "bench_bspline: solve failed\n");
            return 1;
        }
    }
    for (r = 0; r < max; r++) {
        for (k = 0; k < ROUND_CASES; k++) {
            double t0, c0;
            c = (r & 1) ? ROUND_CASES - 1 - k : k;
            t0 = now();
            c0 = cpu_now();
            if (it2n_bspline_solve(&b[c].mdl, &b[c].ds, NULL) != IT2N_OK) {
                fprintf(stderr, "bench_bspline: solve failed\n");
                return 1;
            }
            cpu[c] = (cpu_now() - c0) * 1e3;
            wall[c] = (now() - t0) * 1e3;
        }
        printf("R host.round");
        for (c = 0; c < ROUND_CASES; c++) {
            printf(" %s %.3f %.3f", round_case[c].key, wall[c], cpu[c]);
        }
        printf("\n");
        fflush(stdout);
    }
    for (c = 0; c < ROUND_CASES; c++) {
        drop(&b[c]);
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--rounds") == 0) {
        int max = atoi(argv[2]);
        return max < 2 || max > 1000 ? 2 : rounds(max);
    }
    if (argc == 3 && strcmp(argv[1], "--eval") == 0) {
        bmodel b;
        unsigned pts = (unsigned)atoi(argv[2]);
        if (pts < 2u || pts > 256u) {
            return 2;
        }
        build(&b, pts, IT2N_F_Z);
        if (it2n_bspline_solve(&b.mdl, &b.ds, NULL) != IT2N_OK || eval_many(&b, 256u)) {
            return 1;
        }
        drop(&b);
        return 0;
    }
    if (argc == 2 && strcmp(argv[1], "--time") == 0) {
        printf("B-spline kind, host (best of 3 solves; wall clock, machine load applies):\n");
        time_one(4, IT2N_F_Z, "type-2 x,y,z");
        time_one(32, IT2N_F_Z, "type-2 x,y,z");
        time_one(64, IT2N_F_Z, "type-2 x,y,z");
        time_one(256, IT2N_F_TYPE1 | IT2N_F_Z, "type-1 x,y,z");
        time_one(256, IT2N_F_Z, "type-2 x,y,z");
        return 0;
    }
    fprintf(stderr, "usage: bench_bspline --time | --rounds MAX | --eval POINTS\n");
    return 2;
}
