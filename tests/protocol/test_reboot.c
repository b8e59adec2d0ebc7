/* Unit tests: exactly once across reboots of a deterministic instrument
 * (docs/protocol.md 4.1, v1.2). The client boots with the same first
 * sequence number every time (no entropy, no storage) and is killed at
 * random points; the bytes it had on the line when it died reach the
 * server after its next boot's HELLO (stale frames), and the server's
 * bytes for the dead boot reach the new one. The server is a link that
 * stores entries like it2nd (CONFIGURE clears, an equal re-sent entry is a
 * success, a different one DUPLICATE). Checked after every boot: every
 * entry the boot got ACKed is stored with its value; at the end the store
 * holds exactly the last boot's data set (0 stale entries). The same run
 * with v1.1 and a fixed session id shows the old handshake failing. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "proto_test.h"

#define NE 24         /* entries per data set: 24 PUTs of one entry */
#define RTO 40u

typedef struct server {
    it2n_link l;
    mem_out out;
    it2n_ostream os;
    uint32_t handed;            /* session ids handed out */
    int64_t val[8][8][7];
    uint8_t have[8][8][7];
    unsigned hellos, configures;
} server;

typedef struct client {
    it2n_link l;
    mem_out out;
    it2n_ostream os;
    int step;                   /* 0 HELLO, 1 CONFIGURE, 2.. PUT k = step-2 */
    int set;                    /* data set of this boot (alternating)    */
    uint16_t put_seq[NE];
    uint8_t put_acked[NE], cfg_acked, hello_done;
    int failed;                 /* a NACK or timeout */
    uint32_t hello_at;          /* when the server's HELLO arrived */
} client;

static server *S;
static client *C;
static uint32_t now;

static uint32_t new_session(void *app)
{
    server *s = app;
    return 0xAB000000u + ++s->handed;
}

static int64_t value(int set, unsigned k)
{
    return (int64_t)(set ? 7000 : 3000) + (int64_t)k;
}

static void entry_of(unsigned k, unsigned *i, unsigned *j, unsigned *fp)
{
    *i = k % 4u;
    *j = (k / 4u) % 3u;
    *fp = k / 12u;
}

static int srv_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    server *s = app;
    switch (m->type) {
    case IT2N_MSG_HELLO: {
        it2n_msg r;
        s->hellos++;
        it2n_link_complete(&s->l, seq, 0, NULL);
        memset(&r, 0, sizeof r);
        r.type = IT2N_MSG_HELLO;
        r.u.hello.version_min = IT2N_PROTO_VERSION;
        r.u.hello.version_max = IT2N_PROTO_VERSION_12;
        r.u.hello.window = 4;
        r.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
        r.u.hello.caps = IT2N_CAP_SERVER;
        (void)it2n_link_send(&s->l, &r, now);
        return IT2N_LINK_DEFER;
    }
    case IT2N_MSG_CONFIGURE:
        s->configures++;
        memset(s->have, 0, sizeof s->have);
        return 0;
    case IT2N_MSG_PUT: {
        const it2n_put_entry *e = &m->u.put.e[0];
        if (s->have[e->i][e->j][e->fp])
            return s->val[e->i][e->j][e->fp] == e->vals[0] ? 0 : IT2N_ERR_DUPLICATE;
        s->have[e->i][e->j][e->fp] = 1;
        s->val[e->i][e->j][e->fp] = e->vals[0];
        return 0;
    }
    default:
        return 0;
    }
}

static int cl_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    client *c = app;
    (void)seq;
    if (m->type == IT2N_MSG_HELLO && !c->hello_at)
        c->hello_at = now;
    return 0;
}

static void cl_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *n)
{
    client *c = app;
    (void)n;
    if (code != 0) {
        c->failed = code;
        return;
    }
    if (type == IT2N_MSG_HELLO)
        c->hello_done = 1;
    else if (type == IT2N_MSG_CONFIGURE)
        c->cfg_acked = 1;
    else if (type == IT2N_MSG_PUT)
        for (unsigned k = 0; k < NE; k++)
            if (c->put_seq[k] == seq && c->step > (int)k + 2)
                c->put_acked[k] = 1;
}

static void server_init(int v12)
{
    it2n_link_cfg c;
    memset(S, 0, sizeof *S);
    S->os = mem_stream(&S->out);
    memset(&c, 0, sizeof c);
    c.out = &S->os;
    c.on_rx = srv_rx;
    c.app = S;
    c.rto_ms = RTO;
    c.first_seq = 4242;
    c.session = 0x5E7E0001u;
    c.new_session = v12 ? new_session : NULL;
    assert_int_equal(it2n_link_init(&S->l, &c), IT2N_OK);
}

/* A boot of the deterministic instrument: the same configuration every
 * time (v1.1: the same session id too, as a board without entropy has). */
static void client_boot(int v12, int set)
{
    it2n_link_cfg c;
    memset(C, 0, sizeof *C);
    C->os = mem_stream(&C->out);
    C->set = set;
    memset(&c, 0, sizeof c);
    c.out = &C->os;
    c.on_rx = cl_rx;
    c.on_done = cl_done;
    c.app = C;
    c.rto_ms = RTO;
    c.max_tries = 0;
    c.first_seq = 100;
    c.session = 0x1D;
    c.version = v12 ? IT2N_PROTO_VERSION_12 : 0;
    assert_int_equal(it2n_link_init(&C->l, &c), IT2N_OK);
}

/* The client sends what its protocol allows: HELLO, CONFIGURE alone (a
 * barrier), then PUTs within the window. */
static void client_send(void)
{
    it2n_msg m;
    for (int guard = 0; guard < 8 && C->step < NE + 2; guard++) {
        memset(&m, 0, sizeof m);
        if (C->step == 0) {
            m.type = IT2N_MSG_HELLO;
            m.u.hello.version_min = m.u.hello.version_max =
                C->l.cfg.version ? IT2N_PROTO_VERSION_12 : IT2N_PROTO_VERSION;
            m.u.hello.window = 4;
            m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
            m.u.hello.caps = IT2N_CAP_INSTRUMENT;
        } else if (C->step == 1) {
            if (it2n_link_pending(&C->l) != 0)
                return;
            m = (it2n_msg){0};
            m.type = IT2N_MSG_CONFIGURE;
            m.u.configure.model = 1;
            m.u.configure.n = 3;
            m.u.configure.m = 2;
        } else {
            unsigned k = (unsigned)C->step - 2u, i, j, fp;
            if (!C->cfg_acked || !it2n_link_can_send(&C->l))
                return;
            entry_of(k, &i, &j, &fp);
            m.type = IT2N_MSG_PUT;
            m.u.put.model = 1;
            m.u.put.count = 1;
            m.u.put.e[0].i = (uint8_t)i;
            m.u.put.e[0].j = (uint8_t)j;
            m.u.put.e[0].fp = (uint8_t)fp;
            m.u.put.e[0].vals[0] = value(C->set, k);
        }
        int32_t seq = it2n_link_send(&C->l, &m, now);
        if (seq < 0)
            return;
        if (C->step >= 2)
            C->put_seq[C->step - 2] = (uint16_t)seq;
        C->step++;
    }
}

/* Bytes on the line, each direction: delivered in one piece, or lost. */
static uint64_t rng;
static unsigned loss_pct;

static void carry(mem_out *from, it2n_link *to)
{
    if (from->len && rng_below(&rng, 100) >= loss_pct)
        it2n_link_input(to, from->buf, from->len, now);
    from->len = 0;
}

static void tick(void)
{
    now += 5;
    client_send();
    carry(&C->out, &S->l);
    carry(&S->out, &C->l);
    it2n_link_poll(&S->l, now);
    it2n_link_poll(&C->l, now);
}

typedef struct result {
    unsigned stale, lost, slow_hello, nacked, max_hello_ms;
} result;

/* Entries of the store not of data set `set` (stale), and entries the
 * boot got ACKed that are absent or not its own (lost). */
static void audit(int set, unsigned *stale, unsigned *lost)
{
    for (unsigned k = 0; k < NE; k++) {
        unsigned i, j, fp;
        entry_of(k, &i, &j, &fp);
        /* once the boot's CONFIGURE is ACKed, nothing older may remain */
        if (C->cfg_acked && S->have[i][j][fp] && S->val[i][j][fp] != value(set, k))
            (*stale)++;
        if (C->put_acked[k] && (!S->have[i][j][fp] || S->val[i][j][fp] != value(set, k)))
            (*lost)++;
    }
}

static result run(int v12, unsigned boots, unsigned loss, uint64_t seed)
{
    result r = {0, 0, 0, 0, 0};
    rng = seed;
    loss_pct = loss;
    now = 1000;
    server_init(v12);
    for (unsigned b = 0; b < boots; b++) {
        int last = b + 1 == boots;
        /* What the dying boot left on the line, both ways. */
        mem_out *to_srv = calloc(1, sizeof *to_srv), *to_cl = calloc(1, sizeof *to_cl);
        memcpy(to_srv, &C->out, sizeof *to_srv);
        memcpy(to_cl, &S->out, sizeof *to_cl);
        C->out.len = S->out.len = 0;
        uint32_t boot_at = now;
        client_boot(v12, (int)(b & 1u));
        /* run until killed: a random point (during HELLO, CONFIGURE, PUTs)
         * or, for the last boot, until everything is ACKed */
        unsigned life = last ? 4000u : rng_below(&rng, 60);
        int stale_sent = 0;
        for (unsigned t = 0; t < life && !C->failed; t++) {
            tick();
            if (!stale_sent && (C->hello_done || t > 10)) {
                /* the previous boot's frames arrive late, after the new
                 * HELLO; its ACKs reach the new boot */
                it2n_link_input(&S->l, to_srv->buf, to_srv->len, now);
                it2n_link_input(&C->l, to_cl->buf, to_cl->len, now);
                stale_sent = 1;
            }
            if (last && C->step == NE + 2 && it2n_link_pending(&C->l) == 0)
                break;
        }
        free(to_srv);
        free(to_cl);
        if (C->failed)
            r.nacked++;
        if (v12 && C->hello_at) {
            unsigned ms = C->hello_at - boot_at;
            if (ms > r.max_hello_ms)
                r.max_hello_ms = ms;
        }
        audit(C->set, &r.stale, &r.lost);
        if (last) {
            /* everything of the last data set is there */
            for (unsigned k = 0; k < NE; k++)
                r.lost += !C->put_acked[k];
        }
    }
    return r;
}

static void test_v12_reboots_no_loss(void **st)
{
    (void)st;
    result r = run(1, 1000, 0, 0x5EEDull);
    printf("v1.2, 1000 reboots, clean line: %u stale, %u lost, %u refused, HELLO answered within %u ms\n",
           r.stale, r.lost, r.nacked, r.max_hello_ms);
    assert_int_equal(r.stale, 0);
    assert_int_equal(r.lost, 0);
    assert_int_equal(r.nacked, 0);
    /* one HELLO exchange (a tick each way) plus 2 RTO at most */
    assert_true(r.max_hello_ms <= 2u * RTO + 10u);
}

static void test_v12_reboots_lossy(void **st)
{
    (void)st;
    result r = run(1, 1000, 10, 0xB007ull);
    printf("v1.2, 1000 reboots, 10 %% loss: %u stale, %u lost, %u refused\n", r.stale, r.lost, r.nacked);
    assert_int_equal(r.stale, 0);
    assert_int_equal(r.lost, 0);
    assert_int_equal(r.nacked, 0);
}

/* The same run with the v1.1 handshake: the new boot's frames are taken
 * for the old one's (re-ACKed, not applied) or the old one's applied to
 * the new. The test asserts the failure, so it shows what v1.2 fixes. */
static void test_v11_fixed_id_fails(void **st)
{
    (void)st;
    result r = run(0, 200, 0, 0x5EEDull);
    printf("v1.1, fixed session id, 200 reboots: %u stale, %u lost, %u refused\n", r.stale, r.lost, r.nacked);
    assert_true(r.stale + r.lost + r.nacked > 0);
}

/* The server restarts (forgets the session): the client's frames get
 * NACK SESSION, its link sends HELLO again by itself and goes on in the
 * new session; nothing is lost, the limits are announced again. */
static void test_v12_server_restart(void **st)
{
    (void)st;
    rng = 77;
    loss_pct = 0;
    now = 1000;
    server_init(1);
    client_boot(1, 0);
    for (int t = 0; t < 6; t++)
        tick();
    assert_true(C->cfg_acked);
    assert_true(C->step > 4 && C->step < NE + 2);
    uint32_t before = C->l.stats.tx_hellos;
    /* restart: the store survives (a WAL), the link state does not */
    int64_t val[8][8][7];
    uint8_t have[8][8][7];
    memcpy(val, S->val, sizeof val);
    memcpy(have, S->have, sizeof have);
    server_init(1);
    memcpy(S->val, val, sizeof val);
    memcpy(S->have, have, sizeof have);
    S->handed = 100;
    for (int t = 0; t < 400 && !(C->step == NE + 2 && it2n_link_pending(&C->l) == 0); t++)
        tick();
    assert_int_equal(C->failed, 0);
    assert_int_equal(C->l.stats.tx_hellos, before + 1); /* asked once more */
    assert_int_equal(S->hellos, 1);                    /* limits again */
    assert_int_equal(S->configures, 0);                /* not re-sent */
    unsigned stale = 0, lost = 0;
    audit(0, &stale, &lost);
    for (unsigned k = 0; k < NE; k++)
        lost += !C->put_acked[k];
    assert_int_equal(stale, 0);
    assert_int_equal(lost, 0);
    assert_int_equal(it2n_link_session(&C->l), 0xAB000000u + 101u);
}

/* Frames of a session the server does not know are refused with SESSION,
 * tagged with that session, and never delivered; session 0 is for HELLO. */
static void test_v12_foreign_refused(void **st)
{
    (void)st;
    now = 1000;
    server_init(1);
    uint8_t raw[64], wire[96];
    /* a v1.2 CONFIGURE of session 0x77 nobody handed out */
    it2n_msg m = {0};
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.model = 1;
    m.u.configure.n = 2;
    m.u.configure.m = 2;
    raw[0] = 0x77;
    raw[1] = raw[2] = raw[3] = 0;
    int n = it2n_msg_pack(&m, raw + 4, sizeof raw - 4, NULL);
    it2n_frame_hdr h = {IT2N_PROTO_VERSION_12, IT2N_MSG_CONFIGURE, IT2N_FLAG_REL | IT2N_FLAG_SYN, 9,
                        (uint16_t)(n + 4)};
    int w = it2n_frame_encode(&h, raw, (size_t)n + 4, wire, sizeof wire);
    it2n_link_input(&S->l, wire, (size_t)w, now);
    assert_int_equal(S->configures, 0);
    assert_int_equal(S->l.stats.rx_foreign, 1);
    /* the answer: NACK SESSION, framed v1.2 after session 0x77 */
    it2n_frame_decoder d;
    it2n_frame_decoder_init(&d);
    size_t used;
    const uint8_t *p;
    it2n_frame_hdr g;
    assert_int_equal(it2n_frame_decode(&d, S->out.buf, S->out.len, &used, &g, &p), 1);
    assert_int_equal(g.version, IT2N_PROTO_VERSION_12);
    assert_int_equal(g.type, IT2N_MSG_NACK);
    assert_int_equal(p[0], 0x77);
    it2n_msg a;
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_NACK, p + 4, g.len - 4u, &a, NULL), IT2N_OK);
    assert_int_equal(a.u.nack.code, IT2N_PROTO_ERR_SESSION);
    assert_int_equal(a.u.nack.value, 0x77);
    assert_int_equal(a.u.nack.seq, 9);
    /* session 0 for anything but HELLO: refused too */
    S->out.len = 0;
    raw[0] = 0;
    w = it2n_frame_encode(&h, raw, (size_t)n + 4, wire, sizeof wire);
    it2n_link_input(&S->l, wire, (size_t)w, now);
    assert_int_equal(S->configures, 0);
    assert_int_equal(S->l.stats.rx_foreign, 2);

    /* a malformed HELLO with session 0 (window 0: FIELD) changes nothing:
     * a session in progress keeps going, no id is handed out */
    client_boot(1, 0);
    for (int t = 0; t < 4; t++)
        tick();
    uint32_t sess = it2n_link_session(&S->l), handed = S->handed;
    assert_true(sess != 0u && sess == it2n_link_session(&C->l));
    it2n_msg hm = {0};
    hm.type = IT2N_MSG_HELLO;
    hm.u.hello.version_min = hm.u.hello.version_max = IT2N_PROTO_VERSION_12;
    hm.u.hello.window = 4;
    hm.u.hello.max_payload = 1024;
    memset(raw, 0, 4);
    n = it2n_msg_pack(&hm, raw + 4, sizeof raw - 4, NULL);
    raw[4 + 3] = 0; /* window 0 */
    it2n_frame_hdr hh = {IT2N_PROTO_VERSION_12, IT2N_MSG_HELLO, IT2N_FLAG_REL | IT2N_FLAG_SYN, 5, (uint16_t)(n + 4)};
    w = it2n_frame_encode(&hh, raw, (size_t)n + 4, wire, sizeof wire);
    S->out.len = 0;
    it2n_link_input(&S->l, wire, (size_t)w, now);
    assert_int_equal(it2n_link_session(&S->l), sess);
    assert_int_equal(S->handed, handed);
    assert_int_equal(it2n_frame_decode(&d, S->out.buf, S->out.len, &used, &g, &p), 1);
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_NACK, p + 4, g.len - 4u, &a, NULL), IT2N_OK);
    assert_int_equal(a.u.nack.code, IT2N_PROTO_ERR_FIELD);
    assert_int_equal(a.u.nack.lo, 3);
    S->out.len = 0;
    for (int t = 0; t < 400 && !(C->step == NE + 2 && it2n_link_pending(&C->l) == 0); t++)
        tick();
    assert_int_equal(C->failed, 0);
    assert_int_equal(S->hellos, 1);
    unsigned stale = 0, lost = 0;
    audit(0, &stale, &lost);
    assert_int_equal(stale + lost, 0);
}


/* ---- docs/protocol.md Appendix B, reproduced frame by frame ---------- */

static mem_out ex_out;
static char ex_text[4096];
static size_t ex_len;

static void ex_dump(const char *title)
{
    ex_len += (size_t)snprintf(ex_text + ex_len, sizeof ex_text - ex_len, "%s\n", title);
    for (size_t k = 0; k < ex_out.len; k++)
        ex_len += (size_t)snprintf(ex_text + ex_len, sizeof ex_text - ex_len, "%02x%s", ex_out.buf[k],
                                   ex_out.buf[k] == 0 ? "\n" : " ");
}

static uint32_t ex_session(void *app)
{
    (void)app;
    return 0x1D2C3B4Au;
}

static it2n_link *ex_srv;

static int ex_srv_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    (void)app;
    if (m->type == IT2N_MSG_HELLO) {
        it2n_msg h;
        memset(&h, 0, sizeof h);
        it2n_link_complete(ex_srv, seq, 0, NULL);
        h.type = IT2N_MSG_HELLO;
        h.u.hello.version_min = 2;
        h.u.hello.version_max = 3;
        h.u.hello.max_degree = 7;
        h.u.hello.window = 16;
        h.u.hello.caps = 0x3E;
        h.u.hello.max_payload = 1024;
        h.u.hello.max_models = 1;
        memcpy(h.u.hello.node, "it2nd", 5);
        it2n_link_send(ex_srv, &h, 0);
        return IT2N_LINK_DEFER;
    }
    /* a COMMIT of model 9: the answer is deferred (RCVD) */
    return m->type == IT2N_MSG_COMMIT && m->u.model.model == 9 ? IT2N_LINK_DEFER : 0;
}

/* Frame k (0 = first) of out, as ex_out. */
static void ex_frame(const mem_out *out, unsigned k)
{
    size_t a = 0, b;
    for (; k > 0 && a < out->len; a++)
        if (out->buf[a] == 0)
            k--;
    for (b = a; b < out->len && out->buf[b] != 0; b++)
        ;
    assert_true(b < out->len);
    ex_out.len = b - a + 1;
    memcpy(ex_out.buf, out->buf + a, ex_out.len);
}

static int ex_cl_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    (void)app;
    (void)seq;
    (void)m;
    return 0;
}

static void test_v12_doc_example(void **st)
{
    (void)st;
    static mem_out co, so;
    it2n_ostream cos = mem_stream(&co), sos = mem_stream(&so);
    it2n_link_cfg c, sc;
    it2n_msg h, m;
    memset(&c, 0, sizeof c);
    memset(&sc, 0, sizeof sc);
    c.out = &cos;
    c.on_rx = ex_cl_rx;
    c.rto_ms = 100;
    c.first_seq = 0x100;
    c.version = IT2N_PROTO_VERSION_12;
    sc.out = &sos;
    sc.on_rx = ex_srv_rx;
    sc.rto_ms = 100;
    sc.first_seq = 0x2000;
    sc.session = 1;
    sc.new_session = ex_session;
    ex_srv = &S->l;
    assert_int_equal(it2n_link_init(&C->l, &c), IT2N_OK);
    assert_int_equal(it2n_link_init(&S->l, &sc), IT2N_OK);
    memset(&h, 0, sizeof h);
    h.type = IT2N_MSG_HELLO;
    h.u.hello.version_min = h.u.hello.version_max = 3;
    h.u.hello.max_degree = 7;
    h.u.hello.window = 4;
    h.u.hello.caps = IT2N_CAP_INSTRUMENT;
    h.u.hello.max_payload = 1024;
    h.u.hello.max_models = 1;
    memcpy(h.u.hello.node, "inst-0001", 9);
    ex_len = 0;
    assert_int_equal(it2n_link_send(&C->l, &h, 0), 0x100);
    ex_out = co;
    ex_dump("client HELLO, SYN, session 0, seq 0x0100:");
    it2n_link_input(&S->l, co.buf, co.len, 1);
    co.len = 0;
    /* the server's ACK and HELLO: split at the first delimiter */
    size_t first = 0;
    while (first < so.len && so.buf[first] != 0)
        first++;
    ex_out.len = first + 1;
    memcpy(ex_out.buf, so.buf, first + 1);
    ex_dump("server ACK (session 0, seq 0x0100):");
    ex_out.len = so.len - first - 1;
    memcpy(ex_out.buf, so.buf + first + 1, ex_out.len);
    ex_dump("server HELLO, SYN, session 0x1D2C3B4A (its own sequence, 0x2000):");
    it2n_link_input(&C->l, so.buf, so.len, 2);
    so.len = 0;
    assert_int_equal(it2n_link_session(&C->l), 0x1D2C3B4Au);
    ex_out = co;
    ex_dump("client ACK of it (session 0x1D2C3B4A, seq 0x2000):");
    it2n_link_input(&S->l, co.buf, co.len, 3);
    co.len = 0;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_COMMIT;
    m.u.model.model = 2;
    assert_int_equal(it2n_link_send(&C->l, &m, 4), 0x100);
    ex_out = co;
    ex_dump("client COMMIT model 2, SYN (a new sequence in the session), seq 0x0100:");
    it2n_link_input(&S->l, co.buf, co.len, 5);
    ex_out = so;
    ex_dump("server ACK (session 0x1D2C3B4A, seq 0x0100):");
    assert_int_equal(it2n_link_session(&S->l), 0x1D2C3B4Au);
    it2n_link_input(&C->l, so.buf, so.len, 6);
    so.len = 0;
    assert_int_equal(it2n_link_pending(&C->l), 0);
    /* selective acknowledgement: 0x0101 is lost, 0x0102 and 0x0103 kept */
    m.u.model.model = 3;
    for (unsigned k = 0; k < 3; k++) {
        assert_int_equal(it2n_link_send(&C->l, &m, 7), 0x101 + (int)k);
        if (k == 0)
            co.len = 0;
    }
    it2n_link_input(&S->l, co.buf, co.len, 8);
    co.len = 0;
    ex_frame(&so, 1);
    ex_dump("server GAP (0x0101 lost): misses 0x0101, has just kept 0x0103, holds 0x0102 and 0x0103 (held = 3):");
    it2n_link_input(&C->l, so.buf, so.len, 9); /* the first GAP brings 0x0101 again */
    so.len = 0;
    ex_out = co;
    ex_dump("client COMMIT 0x0101 again (RETX):");
    it2n_link_input(&S->l, co.buf, co.len, 10);
    co.len = 0;
    ex_frame(&so, 2);
    ex_dump("server ACK 0x0103, naming 0x0102, 0x0101, 0x0100 ACKed too (acked = 7):");
    it2n_link_input(&C->l, so.buf, so.len, 11);
    so.len = 0;
    assert_int_equal(it2n_link_pending(&C->l), 0);
    assert_int_equal(C->l.stats.tx_retx, 1);
    m.u.model.model = 9;
    assert_int_equal(it2n_link_send(&C->l, &m, 12), 0x104);
    it2n_link_input(&S->l, co.buf, co.len, 13);
    co.len = 0;
    ex_out = so;
    ex_dump("server RCVD 0x0104 (its answer deferred):");
    it2n_link_input(&C->l, so.buf, so.len, 14);
    so.len = 0;
    assert_int_equal(C->l.stats.rx_rcvd, 1);

    /* the block of docs/protocol.md after its marker */
    FILE *f = fopen("docs/protocol.md", "r");
    if (f == NULL) {
        printf("skip: docs/protocol.md not found from %s (run from the source root)\n", getenv("PWD"));
        return;
    }
    static char doc[1 << 17];
    size_t n = fread(doc, 1, sizeof doc - 1, f);
    fclose(f);
    doc[n] = 0;
    char *at = strstr(doc, "<!-- v1.2 example: test_reboot -->\n```\n");
    assert_non_null(at);
    at = strchr(strchr(at, '\n') + 1, '\n') + 1;
    char *end = strstr(at, "```");
    assert_non_null(end);
    *end = 0;
    if (strcmp(at, ex_text) != 0)
        printf("docs/protocol.md Appendix B should read:\n%s", ex_text);
    assert_string_equal(at, ex_text);
}

static int setup(void **st)
{
    (void)st;
    S = calloc(1, sizeof *S);
    C = calloc(1, sizeof *C);
    return 0;
}

static int teardown(void **st)
{
    (void)st;
    free(S);
    free(C);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_v12_reboots_no_loss, setup, teardown),
        cmocka_unit_test_setup_teardown(test_v12_reboots_lossy, setup, teardown),
        cmocka_unit_test_setup_teardown(test_v11_fixed_id_fails, setup, teardown),
        cmocka_unit_test_setup_teardown(test_v12_server_restart, setup, teardown),
        cmocka_unit_test_setup_teardown(test_v12_foreign_refused, setup, teardown),
        cmocka_unit_test_setup_teardown(test_v12_doc_example, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
