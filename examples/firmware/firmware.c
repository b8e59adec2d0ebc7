/*
 * it2n instrument firmware, emulated: qemu mps2-an385 (Cortex-M3).
 *
 * Synthesises a measured grid (examples/instrument/synth.c: seven nested
 * footprints, z, T/I/F memberships), solves it locally with the core,
 * uploads it over CMSDK UART0 with the serial protocol (HELLO, CONFIGURE,
 * PUT batches, COMMIT through examples/instrument/session.c and the
 * reliable link of protocol/), then QUERYs the peer at a set of (u, w) and
 * checks each QUERY_RESULT bit for bit against its own evaluation. Its own
 * evaluations at the Modbus points are printed over semihosting as
 *   EVAL <u x10000> <w x10000> <out_of_range> <42 values> <12 summary>
 * (raw Q24 integers), for tests/firmware/fw_e2e.sh to compare with Modbus.
 * No heap; everything lives in .bss.
 */
#include <string.h>

#include "board.h"
#include "semihost.h"
#include "session.h"
#include "synth.h"

#ifndef FW_N
#define FW_N 5
#endif
#ifndef FW_M
#define FW_M 4
#endif
#ifndef FW_MODEL
#define FW_MODEL 1
#endif
#ifndef FW_SEED
#define FW_SEED 2026u
#endif
#define FW_RTO_MS 150u
#define FW_TRIES 40u
#define FW_QUERY_WAIT_MS 10000u

/* (u, w) x10000, as written to the Modbus q_u / q_w registers. */
static const uint16_t fw_points[][2] = {
    {0, 0}, {10000, 10000}, {2500, 5000}, {7000, 3000},
    {1234, 8765}, {5000, 5000}, {9999, 1}, {3333, 6667},
};
#define FW_NPOINTS (sizeof fw_points / sizeof fw_points[0])

static it2n_dataset ds;
static it2n_model mdl;
static session sess;
static it2n_point local_pt;

/* QUERY answer capture (the link delivers QUERY_RESULT to on_rx). */
static int32_t q_seq = -1;
static int q_have;
static it2n_msg_query_result q_res;

/* ---- output over semihosting ---- */

static char line[1024];
static size_t line_len;

static void put_str(const char *s)
{
    while (*s != '\0' && line_len < sizeof line - 2u)
        line[line_len++] = *s++;
}

static void put_u64(uint64_t v)
{
    char b[24];
    unsigned n = sizeof b - 1u;
    b[n] = '\0';
    do {
        b[--n] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && n > 0u);
    put_str(&b[n]);
}

static void put_i64(int64_t v)
{
    if (v < 0) {
        put_str("-");
        put_u64((uint64_t)0 - (uint64_t)v);
    } else {
        put_u64((uint64_t)v);
    }
}

static void flush_line(void)
{
    line[line_len++] = '\n';
    line[line_len] = '\0';
    it2n_sh_write0(line);
    line_len = 0;
}

/* ---- streams on UART0 ---- */

static int uart_out(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    (void)s;
    uart_write(buf, len);
    return 0;
}

static int uart_in(it2n_istream *s, uint8_t *buf, size_t len)
{
    (void)s;
    return (int)uart_read(buf, len > 256u ? 256u : len);
}

static it2n_ostream out_stream = {uart_out, NULL};
static it2n_istream in_stream = {uart_in, NULL};

/* Installed on the session's link after the upload: keeps QUERY_RESULTs. */
static int on_rx_query(void *app, uint16_t seq, const it2n_msg *msg)
{
    (void)app, (void)seq;
    if (msg->type == IT2N_MSG_QUERY_RESULT && q_seq >= 0 &&
        msg->u.query_result.re == (uint16_t)q_seq) {
        q_res = msg->u.query_result;
        q_have = 1;
    }
    return 0;
}

/* Q32 parameter from x10000, rounded as it2nd does for q_u / q_w. */
static it2n_par par_from_x10000(uint16_t k)
{
    return (it2n_par)((((uint64_t)k << IT2N_PAR_FRAC) + 5000u) / 10000u);
}

static bool same_point(const it2n_point *a, const it2n_msg_query_result *r)
{
    return memcmp(a->v, r->v, sizeof a->v) == 0 &&
           memcmp(&a->sum, &r->sum, sizeof a->sum) == 0 &&
           a->out_of_range == r->out_of_range;
}

static void print_eval(uint16_t ku, uint16_t kw, const it2n_point *p)
{
    unsigned fp, ch, k;
    put_str("EVAL ");
    put_u64(ku);
    put_str(" ");
    put_u64(kw);
    put_str(" ");
    put_u64(p->out_of_range);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++)
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            put_str(" ");
            put_i64(p->v[fp][ch]);
        }
    /* summary in register order: upper_min, upper_max, lower_min, lower_max */
    for (k = 0; k < 3; k++) { put_str(" "); put_i64(p->sum.upper_min[k]); }
    for (k = 0; k < 3; k++) { put_str(" "); put_i64(p->sum.upper_max[k]); }
    for (k = 0; k < 3; k++) { put_str(" "); put_i64(p->sum.lower_min[k]); }
    for (k = 0; k < 3; k++) { put_str(" "); put_i64(p->sum.lower_max[k]); }
    flush_line();
}

static void fail(const char *what, int64_t code)
{
    put_str("FAIL: ");
    put_str(what);
    put_str(" ");
    put_i64(code);
    flush_line();
}

/* A session id no earlier session of this board used: on hardware, a
 * boot counter in flash or the TRNG; here the board's unique id (none on
 * the emulated board: its clock at start) mixed with the attempt. */
static uint32_t fw_session_id(unsigned attempt)
{
    uint32_t x = board_now_ms() * 2654435761u ^ 0x1F2E3D4Cu;
    return x + attempt * 0x9E3779B9u;
}

/* Upload with session.c; a failed session (peer absent, retries
 * exhausted) starts over with a fresh SYN, up to three times. */
static int upload(void)
{
    unsigned attempt;
    for (attempt = 0; attempt < 3u; attempt++) {
        int st;
        int r = session_init(&sess, &ds, FW_MODEL, &out_stream, &in_stream,
                             FW_RTO_MS, (uint8_t)FW_TRIES, false,
                             (uint16_t)(attempt * 1000u + board_now_ms()),
                             fw_session_id(attempt));
        if (r != IT2N_OK) {
            fail("session_init", r);
            return r;
        }
        while ((st = session_step(&sess, board_now_ms())) == SESSION_RUNNING)
            board_idle();
        if (st == SESSION_DONE)
            return 0;
        fail("upload attempt failed, code", sess.fail_code);
    }
    return -1;
}

static int query(uint32_t wu, uint32_t ww)
{
    it2n_msg m;
    uint32_t t0;
    int32_t seq;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_QUERY;
    m.u.query.model = FW_MODEL;
    m.u.query.u = wu;
    m.u.query.w = ww;
    q_have = 0;
    q_seq = -1;
    t0 = board_now_ms();
    while (!it2n_link_can_send(&sess.link)) {
        (void)it2n_link_pump(&sess.link, board_now_ms());
        (void)it2n_link_poll(&sess.link, board_now_ms());
        board_idle();
    }
    seq = it2n_link_send(&sess.link, &m, board_now_ms());
    if (seq < 0)
        return (int)seq;
    q_seq = seq;
    while (!q_have && board_now_ms() - t0 < FW_QUERY_WAIT_MS) {
        (void)it2n_link_pump(&sess.link, board_now_ms());
        (void)it2n_link_poll(&sess.link, board_now_ms());
        if (sess.state == SESSION_FAILED)
            return sess.fail_code;
        if (!q_have)
            board_idle();
    }
    return q_have ? 0 : IT2N_PROTO_ERR_TIMEOUT;
}

/* Start a new sequence (SYN) on the link and say HELLO again: what a peer
 * does when the other end lost its state (a reopened port NACKs with
 * NOSYNC, or answers never come). */
static unsigned resyncs;

static int resync(void)
{
    it2n_link_cfg cfg = sess.link.cfg;
    it2n_msg m;
    uint32_t t0 = board_now_ms();
    resyncs++;
    cfg.first_seq = (uint16_t)(sess.link.tx_next + 1000u);
    if (it2n_link_init(&sess.link, &cfg) != IT2N_OK)
        return -1;
    sess.state = SESSION_RUNNING;
    sess.fail_code = 0;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_HELLO;
    m.u.hello.version_min = IT2N_PROTO_VERSION_MIN;
    m.u.hello.version_max = IT2N_PROTO_VERSION;
    m.u.hello.max_degree = IT2N_MAX_DEGREE;
    m.u.hello.window = IT2N_PROTO_WINDOW;
    m.u.hello.caps = IT2N_CAP_INSTRUMENT | IT2N_CAP_Z;
    m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
    m.u.hello.max_models = 1;
    memcpy(m.u.hello.node, "it2n-firmware", 13);
    if (it2n_link_send(&sess.link, &m, t0) < 0)
        return -1;
    while (it2n_link_pending(&sess.link) != 0u && sess.state == SESSION_RUNNING &&
           board_now_ms() - t0 < FW_QUERY_WAIT_MS) {
        (void)it2n_link_pump(&sess.link, board_now_ms());
        (void)it2n_link_poll(&sess.link, board_now_ms());
        board_idle();
    }
    return it2n_link_pending(&sess.link) == 0u && sess.state == SESSION_RUNNING ? 0 : -1;
}

/* QUERY, resynchronising the link and asking again when it fails. */
static int query_retry(uint32_t wu, uint32_t ww)
{
    unsigned attempt;
    int r = query(wu, ww);
    for (attempt = 0; r != 0 && attempt < 3u; attempt++) {
        put_str("QUERY failed (");
        put_i64(r);
        put_str("): resynchronising the link; stats rx_delivered ");
        put_u64(sess.link.stats.rx_delivered);
        put_str(" rx_dup ");
        put_u64(sess.link.stats.rx_dup);
        put_str(" rx_ahead ");
        put_u64(sess.link.stats.rx_ahead);
        put_str(" rx_nosync ");
        put_u64(sess.link.stats.rx_nosync);
        put_str(" rx_bad_msg ");
        put_u64(sess.link.stats.rx_bad_msg);
        put_str(" tx_timeouts ");
        put_u64(sess.link.stats.tx_timeouts);
        put_str(" tx_nacked ");
        put_u64(sess.link.stats.tx_nacked);
        put_str(" frames ok ");
        put_u64(sess.link.dec.stats.ok);
        put_str(" crc ");
        put_u64(sess.link.dec.stats.crc);
        put_str(" cobs ");
        put_u64(sess.link.dec.stats.cobs);
        put_str(" other ");
        put_u64((uint64_t)sess.link.dec.stats.shortf + sess.link.dec.stats.oversize +
                sess.link.dec.stats.length + sess.link.dec.stats.version);
        put_str(" rx_acks ");
        put_u64(sess.link.stats.rx_acks);
        put_str(" q_acked ");
        put_u64(it2n_link_pending(&sess.link) == 0u);
        flush_line();
        if (resync() == 0)
            r = query(wu, ww);
    }
    return r;
}

int main(void)
{
    it2n_errinfo err;
    uint32_t t0, t1;
    unsigned k, mismatches = 0;
    int r;

    board_init();
    it2n_sh_write0("it2n firmware: mps2-an385 Cortex-M3, UART0 115200\n");
    r = synth_dataset(&ds, FW_N, FW_M, IT2N_F_Z, FW_SEED, &err);
    if (r != IT2N_OK) {
        fail("synth_dataset", r);
        return 1;
    }
    it2n_model_init(&mdl);
    r = it2n_model_solve(&mdl, &ds, &err);
    if (r != IT2N_OK) {
        fail("local solve", r);
        return 1;
    }
    put_str("local model solved: n ");
    put_u64(FW_N);
    put_str(" m ");
    put_u64(FW_M);
    put_str(" flags z");
    flush_line();

    t0 = board_now_ms();
    if (upload() != 0)
        return 1;
    t1 = board_now_ms();
    put_str("UPLOAD committed ms ");
    put_u64(t1 - t0);
    put_str(" puts ");
    put_u64(sess.puts);
    put_str(" entries ");
    put_u64(sess.entries);
    put_str(" retx ");
    put_u64(sess.link.stats.tx_retx);
    put_str(" rx_overruns ");
    put_u64(uart_rx_overruns());
    flush_line();

    /* From here the firmware consumes what the peer sends itself. */
    sess.link.cfg.on_rx = on_rx_query;

    for (k = 0; k < FW_NPOINTS; k++) {
        it2n_par u = par_from_x10000(fw_points[k][0]);
        it2n_par w = par_from_x10000(fw_points[k][1]);
        uint32_t wu = it2n_par_to_wire(u), ww = it2n_par_to_wire(w);

        /* 1. the peer's answer over the link vs the local core at the
         *    same wire parameters */
        r = it2n_eval(&mdl, it2n_par_from_wire(wu), it2n_par_from_wire(ww),
                      &local_pt, &err);
        if (r != IT2N_OK) {
            fail("local eval (wire)", r);
            return 1;
        }
        r = query_retry(wu, ww);
        if (r != 0) {
            fail("QUERY", r);
            return 1;
        }
        if (!same_point(&local_pt, &q_res)) {
            fail("QUERY_RESULT differs from the local evaluation, point", (int64_t)k);
            mismatches++;
        }

        /* 2. the local evaluation at the Modbus parameters, printed */
        r = it2n_eval(&mdl, u, w, &local_pt, &err);
        if (r != IT2N_OK) {
            fail("local eval", r);
            return 1;
        }
        print_eval(fw_points[k][0], fw_points[k][1], &local_pt);
    }
    put_str("QUERY bit-identical ");
    put_u64(FW_NPOINTS - mismatches);
    put_str("/");
    put_u64(FW_NPOINTS);
    put_str(" retx ");
    put_u64(sess.link.stats.tx_retx);
    put_str(" resyncs ");
    put_u64(resyncs);
    flush_line();
    if (mismatches != 0u)
        return 1;
    it2n_sh_write0("PASS firmware\n");
    return 0;
}
