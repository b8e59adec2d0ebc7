/*
 * Transport under a hostile channel: seeded loss, duplication, reordering,
 * bit corruption, truncation and garbage, in both directions at once, with
 * the receiver deferring some ACKs (as the daemon does until fsync).
 * Checks that every message is delivered exactly once and in order and that
 * every send is ACKed. Deterministic: fixed seeds, simulated clock.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "proto_test.h"

#define QMAX 512
#define NMSG 4000

typedef struct pkt {
    uint32_t at;
    uint16_t len;
    uint8_t b[IT2N_FRAME_MAX_WIRE + 64];
} pkt;

typedef struct chan {
    pkt q[QMAX];
    unsigned n;
    pkt cur;        /* frame being written */
    uint64_t *rng;
    uint32_t *now;
    unsigned drop_pct, dup_pct, corrupt_pct, garbage_pct, max_delay;
    unsigned dropped, duped, corrupted, overflow;
} chan;

static void enqueue(chan *c, const pkt *p, uint32_t delay)
{
    if (c->n == QMAX) {
        c->overflow++; /* a full wire loses data too */
        return;
    }
    c->q[c->n] = *p;
    c->q[c->n].at = *c->now + delay;
    c->n++;
}

static int chan_write(it2n_ostream *s, const uint8_t *b, size_t n)
{
    chan *c = s->state;
    for (size_t k = 0; k < n; k++) {
        if (c->cur.len < sizeof c->cur.b)
            c->cur.b[c->cur.len++] = b[k];
        if (b[k] != 0)
            continue;
        /* one frame complete: decide its fate */
        pkt *p = &c->cur;
        uint64_t *r = c->rng;
        if (rng_below(r, 100) < c->garbage_pct) {
            /* prepend garbage ending in a delimiter */
            uint8_t g[32];
            unsigned gl = 1 + rng_below(r, 30);
            for (unsigned j = 0; j < gl; j++)
                g[j] = (uint8_t)rng_next(r);
            g[gl - 1] = 0;
            memmove(p->b + gl, p->b, p->len);
            memcpy(p->b, g, gl);
            p->len = (uint16_t)(p->len + gl);
        }
        if (rng_below(r, 100) < c->drop_pct) {
            c->dropped++;
        } else {
            if (rng_below(r, 100) < c->corrupt_pct) {
                c->corrupted++;
                if (rng_below(r, 2))
                    p->b[rng_below(r, p->len)] ^= (uint8_t)(1u << rng_below(r, 8));
                else
                    p->len = (uint16_t)rng_below(r, p->len); /* truncated */
            }
            enqueue(c, p, 1 + rng_below(r, c->max_delay));
            if (rng_below(r, 100) < c->dup_pct) {
                c->duped++;
                enqueue(c, p, 1 + rng_below(r, c->max_delay));
            }
        }
        c->cur.len = 0;
    }
    return 0;
}

typedef struct side {
    it2n_link l;
    it2n_ostream os;
    chan *tx;
    uint64_t *rng;
    unsigned defer_pct;
    uint32_t next_expected; /* message number the peer must deliver next */
    uint32_t sent, acked, nacked;
    uint16_t pend[IT2N_PROTO_WINDOW * 2];
    uint32_t pend_at[IT2N_PROTO_WINDOW * 2];
    unsigned npend;
    uint32_t *now;
    int bad;
} side;

static int on_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    side *s = app;
    uint32_t num = m->type == IT2N_MSG_PUT ? (uint32_t)m->u.put.e[0].vals[0]
                                           : m->u.event.generation;
    if (num != s->next_expected) {
        fprintf(stderr, "delivered message %u, expected %u\n", num, s->next_expected);
        s->bad = 1;
    }
    if (m->type == IT2N_MSG_PUT && m->u.put.e[0].vals[5] != -(it2n_val)num * 77)
        s->bad = 2;
    s->next_expected++;
    if (rng_below(s->rng, 100) < s->defer_pct && s->npend < IT2N_PROTO_WINDOW * 2) {
        s->pend[s->npend] = seq;
        s->pend_at[s->npend++] = *s->now + rng_below(s->rng, 30);
        return IT2N_LINK_DEFER;
    }
    return 0;
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *n)
{
    side *s = app;
    (void)seq, (void)type, (void)n;
    if (code == 0)
        s->acked++;
    else {
        fprintf(stderr, "send finished with %d (%s)\n", code, it2n_proto_strerror(code));
        s->nacked++;
    }
}

static void deliver_due(chan *c, it2n_link *to, uint32_t now, uint64_t *rng)
{
    unsigned k = 0;
    while (k < c->n) {
        if ((int32_t)(now - c->q[k].at) < 0) {
            k++;
            continue;
        }
        pkt *p = &c->q[k];
        size_t pos = 0;
        while (pos < p->len) { /* random chunking */
            size_t n = 1 + rng_below(rng, 97);
            if (n > p->len - pos)
                n = p->len - pos;
            it2n_link_input(to, p->b + pos, n, now);
            pos += n;
        }
        c->q[k] = c->q[--c->n]; /* order of the queue is irrelevant */
    }
}

static void run(uint64_t seed, unsigned loss, unsigned nmsg_a, unsigned nmsg_b)
{
    static chan ca, cb;
    static side A, B;
    uint64_t rng = seed;
    uint32_t now = 0;

    memset(&ca, 0, sizeof ca);
    memset(&cb, 0, sizeof cb);
    memset(&A, 0, sizeof A);
    memset(&B, 0, sizeof B);
    chan *cs[2] = {&ca, &cb};
    for (int k = 0; k < 2; k++) {
        cs[k]->rng = &rng;
        cs[k]->now = &now;
        cs[k]->drop_pct = loss;
        cs[k]->dup_pct = loss;
        cs[k]->corrupt_pct = loss;
        cs[k]->garbage_pct = loss;
        cs[k]->max_delay = 25;
    }
    side *ss[2] = {&A, &B};
    for (int k = 0; k < 2; k++) {
        side *s = ss[k];
        s->tx = cs[k];
        s->rng = &rng;
        s->now = &now;
        s->defer_pct = 30;
        s->os.write = chan_write;
        s->os.state = cs[k];
        it2n_link_cfg cfg = {&s->os, NULL, on_rx, on_done, s, 60, 60,
                             (uint16_t)(k ? 65000 : rng_next(&rng)), (uint32_t)rng_next(&rng), 0, 0, 0, 0, NULL};
        assert_int_equal(it2n_link_init(&s->l, &cfg), IT2N_OK);
    }
    unsigned target[2] = {nmsg_a, nmsg_b};
    for (now = 0; now < 50u * 1000u * 1000u; now++) {
        for (int k = 0; k < 2; k++) {
            side *s = ss[k];
            while (s->sent < target[k] && it2n_link_can_send(&s->l)) {
                it2n_msg m;
                memset(&m, 0, sizeof m);
                if (k == 0) {
                    m.type = IT2N_MSG_PUT;
                    m.u.put.count = 1;
                    m.u.put.e[0].fp = (uint8_t)(s->sent % 7);
                    m.u.put.e[0].vals[0] = s->sent;
                    m.u.put.e[0].vals[5] = -(it2n_val)s->sent * 77;
                } else {
                    m.type = IT2N_MSG_EVENT;
                    m.u.event.kind = IT2N_EV_UPDATED;
                    m.u.event.generation = s->sent;
                }
                assert_true(it2n_link_send(&s->l, &m, now) >= 0);
                s->sent++;
            }
            /* deferred answers come due ("fsync finished") */
            for (unsigned j = 0; j < s->npend;) {
                if (now >= s->pend_at[j]) {
                    assert_int_equal(it2n_link_complete(&s->l, s->pend[j], 0, NULL), IT2N_OK);
                    s->pend[j] = s->pend[s->npend - 1];
                    s->pend_at[j] = s->pend_at[--s->npend];
                } else {
                    j++;
                }
            }
            it2n_link_poll(&s->l, now);
        }
        deliver_due(&ca, &B.l, now, &rng);
        deliver_due(&cb, &A.l, now, &rng);
        assert_int_equal(A.bad, 0);
        assert_int_equal(B.bad, 0);
        if (A.acked + A.nacked == nmsg_a && B.acked + B.nacked == nmsg_b &&
            ca.n == 0 && cb.n == 0 && A.npend == 0 && B.npend == 0)
            break;
    }
    printf("seed %llu loss %u%%: %u+%u msgs in %u ms; A retx %u, B retx %u; "
           "dropped %u/%u dup %u/%u corrupted %u/%u; dup-rx %u/%u, "
           "decoder drops %u/%u\n",
           (unsigned long long)seed, loss, nmsg_a, nmsg_b, now,
           A.l.stats.tx_retx, B.l.stats.tx_retx, ca.dropped, cb.dropped,
           ca.duped, cb.duped, ca.corrupted, cb.corrupted, B.l.stats.rx_dup,
           A.l.stats.rx_dup, B.l.dec.stats.crc + B.l.dec.stats.cobs + B.l.dec.stats.shortf,
           A.l.dec.stats.crc + A.l.dec.stats.cobs + A.l.dec.stats.shortf);
    assert_int_equal(A.nacked, 0);
    assert_int_equal(B.nacked, 0);
    assert_int_equal(A.acked, nmsg_a);
    assert_int_equal(B.acked, nmsg_b);
    assert_int_equal(B.next_expected, nmsg_a); /* each delivered once, in order */
    assert_int_equal(A.next_expected, nmsg_b);
    if (loss > 0) { /* the faults really happened */
        assert_true(ca.dropped > 0 && ca.duped > 0 && ca.corrupted > 0);
        assert_true(B.l.stats.rx_dup > 0 && A.l.stats.tx_retx > 0);
        /* v1.1: frames behind a lost one were kept, not dropped */
        assert_true(B.l.stats.rx_buffered > 0 && A.l.stats.rx_buffered > 0);
    }
}

static void test_clean_channel(void **st)
{
    (void)st;
    run(1, 0, NMSG, NMSG / 4);
}

static void test_lossy_5pct(void **st)
{
    (void)st;
    run(2, 5, NMSG, NMSG / 4);
    run(3, 5, NMSG, NMSG / 4);
}

static void test_lossy_20pct(void **st)
{
    (void)st;
    run(4, 20, NMSG / 2, NMSG / 8);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_clean_channel),
        cmocka_unit_test(test_lossy_5pct),
        cmocka_unit_test(test_lossy_20pct),
    };
    return cmocka_run_group_tests_name("proto_lossy", tests, NULL, NULL);
}
