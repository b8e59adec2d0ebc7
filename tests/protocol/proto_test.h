/* Shared helpers for the protocol tests: memory streams and a seeded PRNG. */
#ifndef PROTO_TEST_H
#define PROTO_TEST_H

#include <stdint.h>
#include <string.h>

#include "it2n_link.h"

/* Output stream into a fixed buffer; len grows, overflow sets `full`. */
typedef struct mem_out {
    uint8_t buf[1 << 16];
    size_t len;
    int full, fail;
    unsigned calls;
} mem_out;

static inline int mem_write(it2n_ostream *s, const uint8_t *b, size_t n)
{
    mem_out *m = (mem_out *)s->state;
    m->calls++;
    if (m->fail)
        return -1;
    if (n == 0 || n > 255)
        m->full = 2; /* contract violation, tests assert it never happens */
    if (n > sizeof m->buf - m->len) {
        m->full = 1;
        return 0;
    }
    memcpy(m->buf + m->len, b, n);
    m->len += n;
    return 0;
}

static inline it2n_ostream mem_stream(mem_out *m)
{
    it2n_ostream s = {mem_write, m};
    return s;
}

/* xorshift64*: deterministic, seeded, good enough for fault injection. */
static inline uint64_t rng_next(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return x * 0x2545F4914F6CDD1Dull;
}

static inline unsigned rng_below(uint64_t *s, unsigned n)
{
    return (unsigned)((rng_next(s) >> 33) % n);
}

#endif
