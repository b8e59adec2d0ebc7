/* Unit tests: the instrument API (protocol/it2n_inst.h) against an
 * in-process server built from the link, in both modes (read callback /
 * it2n_inst_feed), with the server announcing small limits. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "it2n_inst.h"
#include "proto_test.h"

/* ---- the server: a link answering like it2nd, with small limits ---- */
typedef struct server {
    it2n_link l;
    mem_out out;
    it2n_ostream os;
    unsigned puts, entries, max_count, configures, commits, hellos;
    uint16_t hello_window, hello_payload;
    int refuse_i7; /* NACK RANGE for a PUT entry at i = 7 */
    int defer_cfg; /* leave CONFIGURE unanswered (cfg_seq) */
    int cfg_open;
    uint16_t cfg_seq;
    unsigned past_barrier; /* frames delivered while a CONFIGURE is open */
    int v13;               /* announce IT2N_CAP_BSPLINE (protocol v1.3) */
    it2n_msg_configure last_cfg;
    uint8_t max_i;         /* largest PUT row index delivered */
    int fine;              /* announce IT2N_CAP_FINE (PUT FINE, v1.3) */
    uint8_t last_put_flags;
    it2n_val last_vals[IT2N_CH_COUNT]; /* of the last entry delivered */
} server;

static server *S;
static uint32_t sessions_handed; /* v1.2 session ids the server gave */

static uint32_t srv_new_session(void *app)
{
    (void)app;
    return 0x5E500000u + ++sessions_handed;
}

static mem_out *to_srv; /* bytes the instrument wrote */
static uint32_t clock_ms;
static it2n_inst *I;

static int srv_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    server *s = app;
    it2n_msg r;
    memset(&r, 0, sizeof r);
    if (s->cfg_open)
        s->past_barrier++;
    switch (m->type) {
    case IT2N_MSG_HELLO:
        s->hellos++;
        it2n_link_complete(&s->l, seq, 0, NULL);
        r.type = IT2N_MSG_HELLO;
        r.u.hello.version_min = IT2N_PROTO_VERSION;
        r.u.hello.version_max = IT2N_PROTO_VERSION_12;
        r.u.hello.window = (uint8_t)s->hello_window;
        r.u.hello.max_payload = s->hello_payload;
        r.u.hello.max_models = 1;
        r.u.hello.caps = IT2N_CAP_SERVER | (s->v13 ? IT2N_CAP_BSPLINE : 0u) |
                         (s->fine ? IT2N_CAP_FINE : 0u);
        assert_true(it2n_link_send(&s->l, &r, clock_ms) >= 0);
        return IT2N_LINK_DEFER;
    case IT2N_MSG_CONFIGURE:
        s->configures++;
        s->last_cfg = m->u.configure;
        if (s->defer_cfg) {
            s->cfg_open = 1;
            s->cfg_seq = seq;
            return IT2N_LINK_DEFER;
        }
        return 0;
    case IT2N_MSG_PUT:
        if ((m->u.put.flags & IT2N_PUT_FINE) && !s->fine) {
            /* what a server without FINE answers (protocol.md 5.4) */
            it2n_errinfo e = {IT2N_PROTO_ERR_FIELD, -1, -1, -1, -1, m->u.put.flags, 1, IT2N_PUT_REPLACE};
            it2n_link_complete(&s->l, seq, IT2N_PROTO_ERR_FIELD, &e);
            return IT2N_LINK_DEFER;
        }
        s->last_put_flags = m->u.put.flags;
        memcpy(s->last_vals, m->u.put.e[m->u.put.count - 1].vals, sizeof s->last_vals);
        s->puts++;
        s->entries += m->u.put.count;
        if (m->u.put.count > s->max_count)
            s->max_count = m->u.put.count;
        for (unsigned k = 0; k < m->u.put.count; k++)
            if (m->u.put.e[k].i > s->max_i)
                s->max_i = m->u.put.e[k].i;
        for (unsigned k = 0; k < m->u.put.count; k++)
            if (s->refuse_i7 && m->u.put.e[k].i == 7) {
                it2n_errinfo e = {IT2N_ERR_RANGE, 7, 0, IT2N_FP_D, IT2N_CH_T, 5, 0, 3};
                it2n_link_complete(&s->l, seq, IT2N_ERR_RANGE, &e);
                return IT2N_LINK_DEFER;
            }
        return 0;
    case IT2N_MSG_COMMIT:
        s->commits++;
        return 0;
    case IT2N_MSG_QUERY:
        if (s->commits == 0)
            return IT2N_ERR_STATE;
        it2n_link_complete(&s->l, seq, 0, NULL);
        r.type = IT2N_MSG_QUERY_RESULT;
        r.u.query_result.re = seq;
        r.u.query_result.model = m->u.query.model;
        r.u.query_result.u = m->u.query.u;
        r.u.query_result.w = m->u.query.w;
        r.u.query_result.v[IT2N_FP_D][IT2N_CH_T] = (it2n_val)m->u.query.u;
        assert_true(it2n_link_send(&s->l, &r, clock_ms) >= 0);
        return IT2N_LINK_DEFER;
    default:
        return IT2N_PROTO_ERR_TYPE;
    }
}

/* Move bytes both ways; the clock advances 1 ms per call. */
static void exchange(void)
{
    clock_ms++;
    if (to_srv->len) {
        size_t n = to_srv->len;
        uint8_t *b = malloc(n);
        memcpy(b, to_srv->buf, n);
        to_srv->len = 0;
        it2n_link_input(&S->l, b, n, clock_ms);
        free(b);
    }
    it2n_link_poll(&S->l, clock_ms);
}

/* ---- the instrument's callbacks ---- */
static int drop_next; /* frames of the instrument to lose */

static int cb_write(void *u, const uint8_t *b, size_t n)
{
    (void)u;
    if (drop_next) {
        if (b[n - 1] == 0)
            drop_next--;
        return 0;
    }
    return mem_write(&(it2n_ostream){mem_write, to_srv}, b, n);
}

static int cb_read(void *u, uint8_t *b, size_t n)
{
    (void)u;
    exchange(); /* the server runs whenever the instrument polls */
    size_t k = S->out.len < n ? S->out.len : n;
    memcpy(b, S->out.buf, k);
    memmove(S->out.buf, S->out.buf + k, S->out.len - k);
    S->out.len -= k;
    return (int)k;
}

static uint32_t cb_now(void *u)
{
    (void)u;
    return clock_ms;
}

static int setup(void **st)
{
    (void)st;
    S = calloc(1, sizeof *S);
    to_srv = calloc(1, sizeof *to_srv);
    I = calloc(1, sizeof *I);
    S->os = mem_stream(&S->out);
    it2n_link_cfg c;
    memset(&c, 0, sizeof c);
    c.out = &S->os;
    c.on_rx = srv_rx;
    c.app = S;
    c.rto_ms = 50;
    c.first_seq = 900;
    c.session = 0xD43;
    c.new_session = srv_new_session; /* serves v1.2 (and v1.1) */
    assert_int_equal(it2n_link_init(&S->l, &c), IT2N_OK);
    S->hello_window = 2;
    S->hello_payload = 4 + 2 * 52; /* PUTs of at most 2 entries */
    clock_ms = 1000;
    drop_next = 0;
    return 0;
}

static int teardown(void **st)
{
    (void)st;
    free(S);
    free(to_srv);
    free(I);
    return 0;
}

static it2n_inst_cfg cfg(int read_mode)
{
    it2n_inst_cfg c;
    memset(&c, 0, sizeof c);
    c.write = cb_write;
    c.now_ms = cb_now;
    c.read = read_mode ? cb_read : NULL;
    c.session_id = 77;
    c.first_seq = 5;
    c.rto_ms = 20;
    c.node = "unit";
    return c;
}

static void vals(it2n_val *v, unsigned i, unsigned j)
{
    memset(v, 0, IT2N_CH_COUNT * sizeof *v);
    v[IT2N_CH_X] = (it2n_val)i << 24;
    v[IT2N_CH_Y] = (it2n_val)j << 24;
    v[IT2N_CH_T] = 1 << 23;
}

static void test_read_mode_upload_and_query(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(1);
    assert_int_equal(it2n_inst_open(I, &c), IT2N_OK);
    assert_int_equal(S->hellos, 1);
    /* the server's HELLO came with the open's wait: its limits bind */
    for (int k = 0; k < 5 && !I->peer_hello; k++)
        it2n_inst_poll(I);
    assert_true(I->peer_hello);
    assert_int_equal(it2n_link_max_payload(&I->link), 108);
    assert_int_equal(it2n_inst_configure(I, 1, 3, 3, 0), IT2N_OK);
    it2n_val v[IT2N_CH_COUNT];
    for (unsigned i = 0; i <= 3; i++)
        for (unsigned j = 0; j <= 3; j++) {
            vals(v, i, j);
            assert_int_equal(it2n_inst_put(I, 1, (uint8_t)i, (uint8_t)j, IT2N_FP_D, v), IT2N_OK);
        }
    /* a QUERY before COMMIT: refused, but the context goes on */
    it2n_msg_query_result res;
    assert_int_equal(it2n_inst_query(I, 1, 5, 6, &res), IT2N_ERR_STATE);
    assert_int_equal(it2n_inst_error(I, NULL), 0);
    assert_int_equal(it2n_inst_commit(I, 1), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->entries, 16);
    assert_int_equal(S->max_count, 2); /* cut to the server's max_payload */
    assert_int_equal(S->puts, 8);
    assert_int_equal(I->entries, 16);
    assert_int_equal(S->commits, 1);
    assert_int_equal(it2n_inst_query(I, 1, 12345, 6, &res), IT2N_OK);
    assert_true(res.v[IT2N_FP_D][IT2N_CH_T] == 12345 && res.u == 12345);
    /* the server never had more than its window in flight from us */
    assert_true(I->link.peer_window == 2);
}

static void test_nack_detail_and_resync(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(1);
    S->refuse_i7 = 1;
    assert_int_equal(it2n_inst_open(I, &c), IT2N_OK);
    it2n_val v[IT2N_CH_COUNT];
    vals(v, 7, 0);
    assert_int_equal(it2n_inst_put(I, 1, 7, 0, IT2N_FP_D, v), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_ERR_RANGE);
    it2n_msg_nack why;
    assert_int_equal(it2n_inst_error(I, &why), IT2N_ERR_RANGE);
    assert_int_equal(why.i, 7);
    assert_int_equal(why.fp, IT2N_FP_D);
    assert_int_equal(why.ch, IT2N_CH_T);
    assert_true(why.value == 5 && why.hi == 3);
    /* refused to send until resync */
    assert_int_equal(it2n_inst_commit(I, 1), IT2N_ERR_RANGE);
    assert_int_equal(it2n_inst_resync(I, 3000), IT2N_OK);
    assert_int_equal(S->hellos, 2);
    assert_int_equal(it2n_inst_commit(I, 1), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->commits, 1);
    /* bad arguments never leave */
    assert_int_equal(it2n_inst_put(I, 1, 8, 0, IT2N_FP_COUNT, v), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(it2n_inst_put(I, 0xFF, 0, 0, IT2N_FP_D, v), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(it2n_inst_configure(I, 1, 0, 3, 0), IT2N_PROTO_ERR_FIELD);
    it2n_inst_cfg bad = c;
    bad.write = NULL;
    assert_int_equal(it2n_inst_open(I, &bad), IT2N_ERR_INVAL);
}

/* v1.3: a B-spline model configured and filled through the instrument
 * API (the 5-byte CONFIGURE, row indices beyond 7); refused locally, with
 * nothing sent, by a server that did not announce IT2N_CAP_BSPLINE. */
static void test_configure_bspline(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(1);
    it2n_val v[IT2N_CH_COUNT];
    assert_int_equal(it2n_inst_open(I, &c), IT2N_OK);
    for (int k = 0; k < 5 && !I->peer_hello; k++)
        it2n_inst_poll(I);
    assert_true(I->peer_hello);
    /* a v1.2 server: VERSION, no frame */
    assert_int_equal(it2n_inst_configure_bspline(I, 1, 63, 63, IT2N_F_Z), IT2N_PROTO_ERR_VERSION);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->configures, 0);
    assert_int_equal(it2n_inst_error(I, NULL), 0); /* the context goes on */
    /* a v1.3 server */
    S->v13 = 1;
    assert_int_equal(it2n_inst_resync(I, 100), IT2N_OK);
    for (int k = 0; k < 5 && !(I->hello.caps & IT2N_CAP_BSPLINE); k++)
        it2n_inst_poll(I);
    /* field errors never leave: CHORD, size 0 */
    assert_int_equal(it2n_inst_configure_bspline(I, 1, 63, 63, IT2N_F_CHORD), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(it2n_inst_configure_bspline(I, 1, 0, 63, 0), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(S->configures, 0);
    assert_int_equal(it2n_inst_configure_bspline(I, 1, 255, 9, IT2N_F_Z | IT2N_F_TYPE1), IT2N_OK);
    for (unsigned i = 250; i <= 255; i++) {
        vals(v, i, 9);
        assert_int_equal(it2n_inst_put(I, 1, (uint8_t)i, 9, IT2N_FP_D, v), IT2N_OK);
    }
    assert_int_equal(it2n_inst_commit(I, 1), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->configures, 1);
    assert_int_equal(S->last_cfg.kind, IT2N_CFG_BSPLINE);
    assert_int_equal(S->last_cfg.n, 255);
    assert_int_equal(S->last_cfg.m, 9);
    assert_int_equal(S->last_cfg.flags, IT2N_F_Z | IT2N_F_TYPE1);
    assert_int_equal(S->entries, 6);
    assert_int_equal(S->max_i, 255);
    /* the Bezier call still sends the 4-byte form */
    assert_int_equal(it2n_inst_configure(I, 1, 3, 3, 0), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->last_cfg.kind, IT2N_CFG_BEZIER);
}

/* v1.3 PUT FINE: memberships in Q30 reach a server announcing
 * IT2N_CAP_FINE bit for bit; one without it gets Q24 when that is exact,
 * and nothing (VERSION, entry not taken) when it is not. */
static void test_put_fine(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(1);
    it2n_val v[IT2N_CH_COUNT];
    assert_int_equal(it2n_inst_open(I, &c), IT2N_OK);
    for (int k = 0; k < 5 && !I->peer_hello; k++)
        it2n_inst_poll(I);
    assert_true(I->peer_hello);
    /* a server without FINE: 0.5 in Q30 is exact in Q24 -> sent as Q24 */
    vals(v, 1, 2);
    v[IT2N_CH_T] = IT2N_MEMB_ONE / 2;
    v[IT2N_CH_F] = IT2N_MEMB_ONE;
    assert_int_equal(it2n_inst_put_fine(I, 1, 1, 2, IT2N_FP_D, v), IT2N_OK);
    assert_int_equal(it2n_inst_flush(I), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->entries, 1);
    assert_int_equal(S->last_put_flags, 0);
    assert_true(S->last_vals[IT2N_CH_T] == IT2N_VAL_ONE / 2);
    assert_true(S->last_vals[IT2N_CH_F] == IT2N_VAL_ONE);
    assert_true(S->last_vals[IT2N_CH_X] == v[IT2N_CH_X]);
    /* 0.9 rounded to 2^-30 is not a multiple of 2^-24: refused, nothing
     * taken, the context goes on */
    v[IT2N_CH_I] = 966367642;
    assert_int_equal(it2n_inst_put_fine(I, 1, 1, 3, IT2N_FP_D, v), IT2N_PROTO_ERR_VERSION);
    assert_int_equal(it2n_inst_flush(I), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->entries, 1);
    assert_int_equal(S->puts, 1);
    assert_int_equal(it2n_inst_error(I, NULL), 0);
    /* field errors: nothing taken */
    assert_int_equal(it2n_inst_put_fine(I, 1, 0, 0, IT2N_FP_COUNT, v), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(it2n_inst_put_fine(I, 0xFF, 0, 0, IT2N_FP_D, v), IT2N_PROTO_ERR_FIELD);
    /* a server announcing FINE: Q30 as is, in a FINE PUT */
    S->fine = 1;
    assert_int_equal(it2n_inst_resync(I, 300), IT2N_OK);
    for (int k = 0; k < 5 && !(I->hello.caps & IT2N_CAP_FINE); k++)
        it2n_inst_poll(I);
    assert_true(I->hello.caps & IT2N_CAP_FINE);
    assert_int_equal(it2n_inst_put_fine(I, 1, 1, 3, IT2N_FP_D, v), IT2N_OK);
    assert_int_equal(it2n_inst_flush(I), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->entries, 2);
    assert_int_equal(S->last_put_flags, IT2N_PUT_FINE);
    assert_memory_equal(S->last_vals, v, sizeof S->last_vals);
    /* a Q24 entry after a fine one: another layout, another PUT */
    unsigned puts = S->puts;
    assert_int_equal(it2n_inst_put_fine(I, 1, 2, 3, IT2N_FP_D, v), IT2N_OK);
    vals(v, 3, 3);
    assert_int_equal(it2n_inst_put(I, 1, 3, 3, IT2N_FP_D, v), IT2N_OK);
    assert_int_equal(it2n_inst_commit(I, 1), IT2N_OK);
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->puts, puts + 2);
    assert_int_equal(S->last_put_flags, 0);
    assert_true(S->last_vals[IT2N_CH_T] == 1 << 23);
}

/* One round in feed mode: the server runs, its bytes are fed to the
 * instrument, which then polls. */
static void feed_round(void)
{
    uint8_t buf[4096];
    exchange();
    size_t n = S->out.len;
    memcpy(buf, S->out.buf, n);
    S->out.len = 0;
    it2n_inst_feed(I, buf, n);
    assert_int_equal(it2n_inst_poll(I), 0);
}

static void test_feed_mode_busy_and_loss(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(0);
    assert_int_equal(it2n_inst_open(I, &c), IT2N_OK);
    /* SYN in flight alone: the next frame has to wait */
    assert_int_equal(it2n_inst_configure(I, 1, 1, 1, 0), IT2N_PROTO_ERR_BUSY);
    unsigned busy = 1, sent = 0; /* the CONFIGURE above */
    it2n_val v[IT2N_CH_COUNT];
    unsigned i = 0;
    drop_next = 1; /* our first frame after HELLO (the ACK of the server HELLO) is lost */
    int configured = 0;
    for (int it = 0; it < 5000 && (sent < 4 || it2n_inst_sync(I) != IT2N_OK || it2n_link_pending(&S->l)); it++) {
        feed_round();
        if (!configured) {
            int r = it2n_inst_configure(I, 1, 1, 1, 0);
            if (r == IT2N_PROTO_ERR_BUSY) {
                busy++;
                continue;
            }
            assert_int_equal(r, IT2N_OK);
            configured = 1;
        }
        if (sent < 4) {
            vals(v, i / 2, i % 2);
            int r = it2n_inst_put(I, 1, (uint8_t)(i / 2), (uint8_t)(i % 2), IT2N_FP_D, v);
            assert_int_equal(r, IT2N_OK);
            i++;
            sent++;
            if (sent == 4) {
                r = it2n_inst_commit(I, 1);
                while (r == IT2N_PROTO_ERR_BUSY) {
                    feed_round();
                    busy++;
                    r = it2n_inst_commit(I, 1);
                }
                assert_int_equal(r, IT2N_OK);
            }
        }
    }
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_true(busy > 0);
    assert_int_equal(S->configures, 1);
    assert_int_equal(S->entries, 4);
    assert_int_equal(S->commits, 1);
    printf("feed mode: %u frames, %u retransmissions, %u busy\n", I->link.stats.tx_frames, I->link.stats.tx_retx, busy);
    assert_true(I->link.stats.tx_retx + S->l.stats.tx_retx > 0); /* the loss was repaired */
    /* a QUERY in feed mode: sent, then done once the result is fed */
    it2n_msg_query_result res;
    memset(&res, 0, sizeof res);
    assert_int_equal(it2n_inst_query(I, 1, 99, 1, &res), IT2N_OK);
    assert_false(it2n_inst_query_done(I));
    for (int it = 0; it < 100 && !it2n_inst_query_done(I); it++)
        feed_round();
    assert_true(it2n_inst_query_done(I));
    assert_true(res.u == 99);
}

/* A CONFIGURE whose answer is outstanding holds everything behind it (a
 * barrier): a PUT ACKed before it would be cleared by the CONFIGURE re-sent
 * after a restart. Before: the PUTs went out in the same window. */
static void test_configure_is_a_barrier(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(0);
    it2n_val v[IT2N_CH_COUNT];
    int r = IT2N_PROTO_ERR_BUSY;
    assert_int_equal(it2n_inst_open(I, &c), IT2N_OK);
    for (int it = 0; it < 100 && it2n_inst_sync(I) != IT2N_OK; it++)
        feed_round(); /* HELLO answered */
    S->defer_cfg = 1;
    assert_int_equal(it2n_inst_configure(I, 1, 1, 1, 0), IT2N_OK);
    unsigned taken = 0, busy = 0;
    for (int it = 0; it < 50; it++) {
        feed_round();
        if (taken < 4) {
            vals(v, taken / 2, taken % 2);
            r = it2n_inst_put(I, 1, (uint8_t)(taken / 2), (uint8_t)(taken % 2), IT2N_FP_D, v);
            if (r == IT2N_OK)
                taken++;
            else
                busy++;
        }
    }
    assert_true(S->cfg_open);
    assert_int_equal(S->past_barrier, 0); /* nothing delivered behind it */
    assert_int_equal(S->puts, 0);
    assert_true(busy > 0);                 /* the caller was told to wait */
    it2n_link_complete(&S->l, S->cfg_seq, 0, NULL);
    S->cfg_open = 0;
    for (int it = 0; it < 200 && (taken < 4 || it2n_inst_sync(I) != IT2N_OK); it++) {
        feed_round();
        if (taken < 4) {
            vals(v, taken / 2, taken % 2);
            if (it2n_inst_put(I, 1, (uint8_t)(taken / 2), (uint8_t)(taken % 2), IT2N_FP_D, v) == IT2N_OK)
                taken++;
        }
    }
    assert_int_equal(it2n_inst_sync(I), IT2N_OK);
    assert_int_equal(S->entries, 4);
    assert_int_equal(S->configures, 1);
    /* and a CONFIGURE waits for what is in flight before it */
    S->defer_cfg = 0;
    vals(v, 0, 0);
    assert_int_equal(it2n_inst_put(I, 1, 0, 0, IT2N_FP_D, v), IT2N_OK);
    assert_int_equal(it2n_inst_flush(I), IT2N_OK);
    assert_int_equal(it2n_inst_configure(I, 1, 1, 1, 0), IT2N_PROTO_ERR_BUSY);
}

/* A daemon that never answers: the session fails with TIMEOUT after
 * max_tries, and says so. */
static void test_silent_peer_times_out(void **st)
{
    (void)st;
    it2n_inst_cfg c = cfg(1);
    c.max_tries = 3;
    c.rto_ms = 10;
    c.timeout_ms = 100000;
    drop_next = 1000;
    assert_int_equal(it2n_inst_open(I, &c), IT2N_PROTO_ERR_TIMEOUT);
    assert_int_equal(it2n_inst_error(I, NULL), IT2N_PROTO_ERR_TIMEOUT);
    assert_int_equal(I->link.stats.tx_frames, 3);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_read_mode_upload_and_query, setup, teardown),
        cmocka_unit_test_setup_teardown(test_nack_detail_and_resync, setup, teardown),
        cmocka_unit_test_setup_teardown(test_feed_mode_busy_and_loss, setup, teardown),
        cmocka_unit_test_setup_teardown(test_silent_peer_times_out, setup, teardown),
        cmocka_unit_test_setup_teardown(test_configure_is_a_barrier, setup, teardown),
        cmocka_unit_test_setup_teardown(test_configure_bspline, setup, teardown),
        cmocka_unit_test_setup_teardown(test_put_fine, setup, teardown),
    };
    return cmocka_run_group_tests_name("proto_inst", tests, NULL, NULL);
}
