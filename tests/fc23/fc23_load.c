/* fc23_load — the client load of the FC 23 benchmark (tests/fc23/).
 *
 * N threads, one Modbus TCP connection each (libmodbus), send FC 23 back
 * to back for a fixed time: write q_u, q_w (registers 64..65, x10000),
 * read the 108-register result block at 128 (float32 v[fp][ch] and the
 * summary, docs/registers.md). Every answer is checked:
 *   --expect model: against the paper model solved and evaluated here with
 *     the core (register values computed independently of the daemon's
 *     mb_map: eval, Q24 -> float, ABCD word order);
 *   --expect pattern: against the fixed pattern the bare server holds
 *     (fc23_bare.c).
 * Each thread cycles through its own sequence of (u, w), so answers to
 * different connections are all different and a reply delivered to the
 * wrong connection, or computed for another connection's query, fails.
 *
 * Each request's latency (send to complete answer, CLOCK_MONOTONIC) goes
 * into a log-linear histogram (64 steps per octave: within 1.6 %).
 *
 * Prints one line: "requests N seconds S rate R errors E mismatches M
 * p50_us L p99_us L" (latency percentiles over all connections).
 * Exit status 0 only when every request was answered and correct. */
#include <errno.h>
#include <modbus.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "it2n.h"
#include "simcommon.h"

#define Q_ADDR 64
#define R_ADDR 128
#define R_COUNT 108
#define NQ 64 /* (u, w) pairs per thread cycle */

static const char *host = "127.0.0.1";
static int port, unit = 1, nthreads = 1;
static double seconds = 1.0;
static int expect_model;
static atomic_int stop;
static uint16_t expected[NQ * 4][R_COUNT];
static uint16_t qregs[NQ * 4][2];

/* Latency histogram in ns: below 128 one bucket per ns, above 64 per
 * octave (bucket 64 e + (v >> e), e = octave - 6). */
#define HBUCKETS (64 * 40 + 128)

static unsigned hbucket(uint64_t ns)
{
    unsigned e = 0;
    while ((ns >> e) >= 128u)
        e++;
    unsigned b = 64u * e + (unsigned)(ns >> e);
    return b < HBUCKETS ? b : HBUCKETS - 1;
}

/* The smallest latency of bucket b, in ns. */
static double hvalue(unsigned b)
{
    if (b < 128)
        return b;
    unsigned e = (b - 64u) / 64u;
    return (double)((uint64_t)(b - 64u * e) << e);
}

struct worker {
    pthread_t th;
    int id;
    long requests, errors, mismatches;
    char first_error[200];
    uint32_t hist[HBUCKETS];
};

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void put_f32(uint16_t out[2], it2n_val v)
{
    float f = (float)((double)v / (double)IT2N_VAL_ONE);
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    out[0] = (uint16_t)(b >> 16);
    out[1] = (uint16_t)b;
}

/* The paper data set solved with the core, as the daemon's preload does
 * (it compiles in the same file, examples/paper_4x4.csv). */
static int paper_model(it2n_model *mdl)
{
    static it2n_dataset ds;
    it2n_errinfo err;
    sim_load_csv("examples/paper_4x4.csv", 0, &ds);
    it2n_model_init(mdl);
    return it2n_model_solve(mdl, &ds, &err) == IT2N_OK ? 0 : -1;
}

static it2n_val sum_value(const it2n_summary *s, unsigned idx)
{
    const it2n_val *sets[4] = { s->upper_min, s->upper_max, s->lower_min, s->lower_max };
    return sets[idx / 3][idx % 3];
}

static int prepare(void)
{
    static it2n_model mdl;
    if (expect_model && paper_model(&mdl))
        return -1;
    for (int k = 0; k < NQ * 4; k++) {
        /* Spread over [0, 1], corners included. */
        unsigned u = (unsigned)(k * 2531u) % 10001u, w = (unsigned)(k * 7919u + 13u) % 10001u;
        if (k == 0)
            u = w = 0;
        if (k == 1)
            u = w = 10000;
        qregs[k][0] = (uint16_t)u;
        qregs[k][1] = (uint16_t)w;
        if (!expect_model) {
            for (int r = 0; r < R_COUNT; r++)
                expected[k][r] = (uint16_t)(0x5A00u + (unsigned)r * 7u);
            continue;
        }
        /* As the map converts x10000 to Q32: round(reg * 2^32 / 10000). */
        it2n_par pu = (it2n_par)(((uint64_t)u * (uint64_t)IT2N_PAR_ONE + 5000u) / 10000u);
        it2n_par pw = (it2n_par)(((uint64_t)w * (uint64_t)IT2N_PAR_ONE + 5000u) / 10000u);
        it2n_point pt;
        if (it2n_eval(&mdl, pu, pw, &pt, NULL) != IT2N_OK)
            return -1;
        for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
            for (unsigned c = 0; c < IT2N_CH_COUNT; c++)
                put_f32(&expected[k][(fp * IT2N_CH_COUNT + c) * 2], pt.v[fp][c]);
        for (unsigned s = 0; s < 12; s++)
            put_f32(&expected[k][84 + s * 2], sum_value(&pt.sum, s));
    }
    return 0;
}

static void note(struct worker *w, const char *what)
{
    if (!w->first_error[0])
        snprintf(w->first_error, sizeof w->first_error, "%s", what);
}

static void *run(void *arg)
{
    struct worker *w = arg;
    uint16_t dest[R_COUNT];
    modbus_t *ctx = modbus_new_tcp(host, port);
    if (!ctx || modbus_set_slave(ctx, unit) < 0 || modbus_connect(ctx) < 0) {
        w->errors++;
        note(w, ctx ? modbus_strerror(errno) : "modbus_new_tcp");
        if (ctx)
            modbus_free(ctx);
        return NULL;
    }
    modbus_set_response_timeout(ctx, 5, 0);
    for (unsigned k = (unsigned)w->id * 17u; !atomic_load_explicit(&stop, memory_order_relaxed); k++) {
        unsigned q = (k + (unsigned)w->id * 3u) % (NQ * 4);
        memset(dest, 0xEE, sizeof dest);
        double t0 = now_s();
        int rc = modbus_write_and_read_registers(ctx, Q_ADDR, 2, qregs[q], R_ADDR, R_COUNT, dest);
        double lat = now_s() - t0;
        if (rc != R_COUNT) {
            w->errors++;
            note(w, rc < 0 ? modbus_strerror(errno) : "short answer");
            if (w->errors > 10)
                break;
            continue;
        }
        w->requests++;
        w->hist[hbucket((uint64_t)(lat * 1e9))]++;
        if (memcmp(dest, expected[q], sizeof dest)) {
            w->mismatches++;
            for (int r = 0; r < R_COUNT; r++)
                if (dest[r] != expected[q][r]) {
                    char m[200];
                    snprintf(m, sizeof m, "u=%u w=%u: register %d is 0x%04x, expected 0x%04x", qregs[q][0],
                             qregs[q][1], R_ADDR + r, dest[r], expected[q][r]);
                    note(w, m);
                    break;
                }
        }
    }
    modbus_close(ctx);
    modbus_free(ctx);
    return NULL;
}

int main(int argc, char **argv)
{
    for (int a = 1; a < argc; a++) {
        const char *v = a + 1 < argc ? argv[a + 1] : NULL;
        if (!strcmp(argv[a], "--port") && v)
            port = atoi(v), a++;
        else if (!strcmp(argv[a], "--host") && v)
            host = v, a++;
        else if (!strcmp(argv[a], "--unit") && v)
            unit = atoi(v), a++;
        else if (!strcmp(argv[a], "--conns") && v)
            nthreads = atoi(v), a++;
        else if (!strcmp(argv[a], "--seconds") && v)
            seconds = atof(v), a++;
        else if (!strcmp(argv[a], "--expect") && v)
            expect_model = !strcmp(v, "model"), a++;
        else {
            fprintf(stderr, "usage: fc23_load --port P [--host H] [--unit U] [--conns N] [--seconds S] "
                            "[--expect model|pattern]\n");
            return 2;
        }
    }
    if (port <= 0 || nthreads < 1 || nthreads > 256 || seconds <= 0) {
        fprintf(stderr, "fc23_load: bad arguments\n");
        return 2;
    }
    if (prepare()) {
        fprintf(stderr, "fc23_load: cannot compute the expected answers\n");
        return 1;
    }
    struct worker *ws = calloc((size_t)nthreads, sizeof *ws);
    if (!ws)
        return 1;
    double t0 = now_s();
    for (int k = 0; k < nthreads; k++) {
        ws[k].id = k;
        pthread_create(&ws[k].th, NULL, run, &ws[k]);
    }
    struct timespec ts = { (time_t)seconds, (long)((seconds - (double)(time_t)seconds) * 1e9) };
    nanosleep(&ts, NULL);
    atomic_store(&stop, 1);
    long req = 0, err = 0, mis = 0;
    for (int k = 0; k < nthreads; k++) {
        pthread_join(ws[k].th, NULL);
        req += ws[k].requests;
        err += ws[k].errors;
        mis += ws[k].mismatches;
        if (ws[k].first_error[0])
            fprintf(stderr, "fc23_load: connection %d: %s\n", k, ws[k].first_error);
    }
    double el = now_s() - t0;
    double pct[2] = { 0, 0 };
    const double want[2] = { 0.50, 0.99 };
    for (int p = 0; p < 2; p++) {
        long need = (long)(want[p] * (double)req + 0.999999), seen = 0;
        for (unsigned b = 0; b < HBUCKETS && need > 0; b++) {
            for (int k = 0; k < nthreads; k++)
                seen += ws[k].hist[b];
            if (seen >= need) {
                pct[p] = hvalue(b) / 1e3;
                break;
            }
        }
    }
    printf("requests %ld seconds %.3f rate %.1f errors %ld mismatches %ld p50_us %.2f p99_us %.2f\n", req, el,
           (double)req / el, err, mis, pct[0], pct[1]);
    free(ws);
    return err || mis || req == 0 ? 1 : 0;
}
