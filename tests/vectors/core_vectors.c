/*
 * Core test-vector checker: recomputes every scenario (vec_scenarios.c) and
 * compares each output bit-exactly with the checked-in core_vectors.h. Runs
 * on the host (make test) and on the emulated Cortex-M3 (tests/qemu/).
 * Freestanding: the caller supplies the log sink; memory is static (.bss).
 */
#include "core_vectors.h"
#include "vec_scenarios.h"

int it2n_core_vectors_run(void (*log)(const char *));

/* Mismatches reported in full before the checker only counts them. */
#define VEC_REPORT_MAX 20u

typedef struct vec_check {
    void (*log)(const char *);
    uint32_t index;
    uint32_t mismatches;
} vec_check;

/* Signed decimal into buf (at least 21 bytes); returns the end. */
static char *fmt_i64(char *buf, int64_t v)
{
    char tmp[20];
    unsigned n = 0;
    uint64_t u = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
    if (v < 0) {
        *buf++ = '-';
    }
    do {
        tmp[n++] = (char)('0' + (char)(u % 10u));
        u /= 10u;
    } while (u != 0u);
    while (n > 0u) {
        *buf++ = tmp[--n];
    }
    *buf = '\0';
    return buf;
}

static char *cat(char *dst, const char *src)
{
    while (*src != '\0') {
        *dst++ = *src++;
    }
    *dst = '\0';
    return dst;
}

static void check_put(void *state, const char *tag, int64_t value)
{
    vec_check *c = state;
    uint32_t k = c->index++;
    int64_t want;
    char line[160];
    char *p;

    if (k >= IT2N_CORE_VECTORS_COUNT) {
        if (k == IT2N_CORE_VECTORS_COUNT) {
            c->log("core vectors: more outputs than expected values\n");
        }
        c->mismatches++;
        return;
    }
    want = it2n_core_vectors_expected[k];
    if (value == want) {
        return;
    }
    if (c->mismatches++ < VEC_REPORT_MAX) {
        p = cat(line, "core vectors: #");
        p = fmt_i64(p, (int64_t)k);
        p = cat(p, " ");
        p = cat(p, tag);
        p = cat(p, ": got ");
        p = fmt_i64(p, value);
        p = cat(p, ", expected ");
        p = fmt_i64(p, want);
        (void)cat(p, "\n");
        c->log(line);
    }
}

int it2n_core_vectors_run(void (*log)(const char *))
{
    static it2n_vec_work work; /* ~50 KB: static, never on the stack */
    vec_check c;
    char line[120];
    char *p;

    c.log = log;
    c.index = 0;
    c.mismatches = 0;
    it2n_vec_scenarios(&work, check_put, &c);
    if (c.index < IT2N_CORE_VECTORS_COUNT) {
        log("core vectors: fewer outputs than expected values\n");
        c.mismatches++;
    }
    p = cat(line, "core vectors: ");
    p = fmt_i64(p, (int64_t)c.index);
    p = cat(p, " outputs checked, ");
    p = fmt_i64(p, (int64_t)c.mismatches);
    (void)cat(p, " mismatches\n");
    log(line);
    return c.mismatches == 0u ? 0 : 1;
}
