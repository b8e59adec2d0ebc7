/*
 * proto_session — one host session against it2nd over a serial link, for
 * the protocol benchmarks (tests/bench/proto/bench_proto.py). It links the
 * protocol library's public link API (protocol/it2n_link.h) and the core,
 * and acts as instrument and host at once:
 *
 *   session: HELLO, CONFIGURE, PUT of every entry, COMMIT, QUERY at Q
 *            parameters one after the other, SAMPLE of footprint D on an
 *            S x S grid; every QUERY_RESULT and SAMPLE_DATA value is
 *            checked bit for bit against the core's own solve of the same
 *            data, and folded into a digest (FNV-1a 64 of the results in
 *            request order) that must equal a clean run's.
 *   ingest:  (--ingest ROUNDS) HELLO, CONFIGURE, then the whole grid PUT
 *            ROUNDS times with the REPLACE flag, COMMIT: entries per second
 *            from the first PUT to the last PUT's ACK (ACK means durable).
 *
 *   proto_session --device PATH | --fd N [--degree NxM] [--queries Q]
 *                 [--sample S] [--ingest ROUNDS [--reconfigure 1]] [--window W]
 *                 [--baud BD] [--rto MS]
 *                 [--tries N] [--rerequest-ms MS] [--timeout S] [--seed S]
 *
 * --fd N: the line is the inherited descriptor N (e.g. the master of a pty
 * pair whose slave the daemon opened) instead of --device.
 * --reconfigure: (with --ingest) each round starts with CONFIGURE (sent in
 * the stream, not waited for) and PUTs without REPLACE: every round fills
 * an empty model (one solve, at its last entry) instead of updating a
 * solved one entry by entry.
 * --baud BD: the line's rate; the RTO then counts from when a frame has
 * left the line, default it2n_link_rto_default(BD) as it2nd (else 150 ms).
 * --window W: the window announced in HELLO and kept to (4..16, a power
 * of two; default 4: the fixed RTO of 150 ms covers 4 maximal frames on a
 * 921600 Bd line, not 16). Frames in flight are min(W, the daemon's HELLO
 * window); "max_in_flight" in the output is the most seen.
 *
 * Host re-requests: a request whose responses stop coming (no new response
 * for --rerequest-ms after the request was ACKed, default 3000), whose
 * delivery timed out, or that was NACKed BUSY is sent again and counted:
 * responses lost for good cost the host a re-request. Answers to any copy
 * of a request count; duplicate points must be identical.
 *
 * Prints one JSON object on stdout. Exit: 0 session complete and every
 * result correct, 1 a result differs or a request was refused, 2 usage,
 * 3 timeout or I/O error.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "it2n_link.h"
#include "synth.h"

#define MAX_NODES 65536u
#define MAX_QUERIES 64u

static int fd = -1;
static it2n_link lk;
static it2n_dataset ds;
static it2n_model local;
static unsigned model_id = 1;

static uint64_t now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint32_t now_ms(void)
{
    return (uint32_t)(now_us() / 1000u);
}

/* it2n_frame_write hands a frame over in COBS blocks of at most 255
 * bytes, the 0x00 delimiter last: collect them and write the frame whole,
 * one write() instead of up to five, so that the daemon wakes up once per
 * frame rather than once per block. */
static uint8_t stage[IT2N_FRAME_MAX_WIRE];
static size_t nstage;

static int fd_write_all(const uint8_t *p, size_t n);

static int fd_write(it2n_ostream *s, const uint8_t *p, size_t n)
{
    (void)s;
    if (n > sizeof stage - nstage) { /* cannot happen: frames fit */
        size_t k = nstage;
        nstage = 0;
        if (fd_write_all(stage, k))
            return IT2N_PROTO_ERR_STREAM;
        return fd_write_all(p, n);
    }
    memcpy(stage + nstage, p, n);
    nstage += n;
    if (p[n - 1] != 0)
        return 0;
    n = nstage;
    nstage = 0;
    return fd_write_all(stage, n);
}

static int fd_write_all(const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t w = write(fd, p, n);
        if (w < 0 && (errno == EAGAIN || errno == EINTR)) {
            struct pollfd q = { fd, POLLOUT, 0 };
            poll(&q, 1, 10);
            continue;
        }
        if (w <= 0)
            return IT2N_PROTO_ERR_STREAM;
        p += w;
        n -= (size_t)w;
    }
    return 0;
}

/* ---- request bookkeeping --------------------------------------------- */

enum { R_RESEND = -1, R_NONE, R_SENT, R_ACKED };

typedef struct req {
    it2n_msg msg;        /* the request, re-sent as is */
    int state;
    int32_t seq;         /* of the latest copy */
    uint64_t progress;   /* us of the ACK or the last new response */
    uint32_t want, got;  /* responses (points / results) */
    int busy_counted;    /* a BUSY refusal of this copy was counted */
} req;

static req cur;
static unsigned busy_retries, rereq_timeout, rereq_busy, rereq_lost, refused, mismatches, dup_diff;
static unsigned ack_entries, put_entries_in_flight[65536];
static uint64_t digest = 0xcbf29ce484222325ULL;
static uint8_t *sample_seen;
static it2n_val (*sample_v)[IT2N_CH_COUNT];
static it2n_msg_query_result qres[MAX_QUERIES];
static unsigned query_k;
/* Pipelined QUERYs (as many in flight as the window takes): per query the
 * request, the sequence number of its latest copy, its state and whether
 * its result arrived. */
static struct {
    it2n_msg msg;
    int32_t seq;
    int state;
    int got;
    uint64_t progress;
} qq[MAX_QUERIES];
static unsigned nqq;
static unsigned rerequest_ms = 3000;
static unsigned in_session_resp;

static void fold(const void *p, size_t n)
{
    const uint8_t *b = p;
    for (size_t k = 0; k < n; k++) {
        digest ^= b[k];
        digest *= 0x100000001b3ULL;
    }
}

static it2n_par node_par(uint32_t k, uint32_t count)
{
    return (it2n_par)(((uint64_t)k << IT2N_PAR_FRAC) / (count - 1u));
}

static int trace;
static uint64_t t_start;

static unsigned max_in_flight, daemon_window;

/* A QUERY_RESULT against the core's own evaluation, bit for bit. */
static void check_result(const it2n_msg_query_result *d)
{
    it2n_point pt;
    it2n_eval(&local, it2n_par_from_wire(d->u), it2n_par_from_wire(d->w), &pt, NULL);
    mismatches += memcmp(pt.v, d->v, sizeof pt.v) != 0;
    mismatches += memcmp(&pt.sum, &d->sum, sizeof pt.sum) != 0;
    mismatches += pt.out_of_range != d->out_of_range;
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    (void)app;
    if (m->type == IT2N_MSG_HELLO) { /* the daemon's limits */
        daemon_window = m->u.hello.window;
        it2n_link_set_peer(&lk, m->u.hello.window, m->u.hello.max_payload);
    }
    if (trace)
        fprintf(stderr, "%9.3f rx %s seq %u\n", (double)(now_us() - t_start) / 1e3, it2n_msg_name(m->type), seq);
    if (m->type == IT2N_MSG_QUERY_RESULT && nqq) {
        const it2n_msg_query_result *d = &m->u.query_result;
        for (unsigned k = 0; k < nqq; k++) {
            if (qq[k].got || qq[k].state == R_NONE || d->u != qq[k].msg.u.query.u || d->w != qq[k].msg.u.query.w)
                continue;
            check_result(d);
            qres[k] = *d;
            qq[k].got = 1;
            break;
        }
    } else if (m->type == IT2N_MSG_QUERY_RESULT && cur.state != R_NONE && cur.msg.type == IT2N_MSG_QUERY &&
        m->u.query_result.u == cur.msg.u.query.u && m->u.query_result.w == cur.msg.u.query.w) {
        const it2n_msg_query_result *d = &m->u.query_result;
        if (cur.got == 0) {
            check_result(d);
            qres[query_k] = *d;
            cur.got = 1;
            cur.progress = now_us();
        }
    } else if (m->type == IT2N_MSG_SAMPLE_DATA && cur.state != R_NONE && cur.msg.type == IT2N_MSG_SAMPLE) {
        const it2n_msg_sample_data *d = &m->u.sample_data;
        if (d->rows != cur.msg.u.sample.rows || d->cols != cur.msg.u.sample.cols || d->fp != cur.msg.u.sample.fp)
            return 0;
        for (unsigned k = 0; k < d->count; k++) {
            uint32_t idx = d->start + k;
            if (idx >= (uint32_t)d->rows * d->cols)
                break;
            if (sample_seen[idx]) {
                dup_diff += memcmp(sample_v[idx], d->v[k], sizeof d->v[k]) != 0;
                continue;
            }
            it2n_point pt;
            it2n_eval(&local, node_par(idx / d->cols, d->rows), node_par(idx % d->cols, d->cols), &pt, NULL);
            mismatches += memcmp(pt.v[d->fp], d->v[k], sizeof d->v[k]) != 0;
            memcpy(sample_v[idx], d->v[k], sizeof d->v[k]);
            sample_seen[idx] = 1;
            cur.got++;
            cur.progress = now_us();
        }
    }
    in_session_resp++;
    return 0; /* the daemon's HELLO, EVENTs and responses: ACK */
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack)
{
    (void)app;
    if (trace)
        fprintf(stderr, "%9.3f done %s seq %u code %d\n", (double)(now_us() - t_start) / 1e3, it2n_msg_name(type),
                seq, code);
    if (type == IT2N_MSG_PUT && code == 0)
        ack_entries += put_entries_in_flight[seq];
    for (unsigned k = 0; k < nqq; k++) {
        if (qq[k].state != R_SENT || (uint16_t)qq[k].seq != seq)
            continue;
        if (code == 0) {
            qq[k].state = R_ACKED;
            qq[k].progress = now_us();
        } else if (code == IT2N_PROTO_ERR_BUSY || code == IT2N_PROTO_ERR_TIMEOUT) {
            qq[k].state = R_RESEND; /* refused while busy, or delivery unknown */
            busy_retries += code == IT2N_PROTO_ERR_BUSY;
            if (code == IT2N_PROTO_ERR_BUSY)
                rereq_busy++;
            else
                rereq_lost++;
        } else {
            fprintf(stderr, "proto_session: QUERY refused: %d (%s)\n", code, it2n_proto_strerror(code));
            refused++;
        }
        return;
    }
    if (cur.state == R_SENT && seq == (uint16_t)cur.seq) {
        if (code == 0) {
            cur.busy_counted = 0;
            cur.state = R_ACKED;
            cur.progress = now_us();
        } else if (code == IT2N_PROTO_ERR_BUSY || code == IT2N_PROTO_ERR_TIMEOUT) {
            /* refused while the daemon was busy, or delivery unknown: ask again */
            cur.state = R_RESEND;
            busy_retries += code == IT2N_PROTO_ERR_BUSY;
            if (code == IT2N_PROTO_ERR_BUSY && !cur.busy_counted) /* once until accepted */
                rereq_busy++;
            else if (code != IT2N_PROTO_ERR_BUSY)
                rereq_lost++;
            cur.busy_counted = code == IT2N_PROTO_ERR_BUSY;
        } else {
            fprintf(stderr, "proto_session: %s refused: %d (%s)", it2n_msg_name(type), code,
                    it2n_proto_strerror(code));
            if (nack)
                fprintf(stderr, " i %d j %d fp %d ch %d", nack->i, nack->j, nack->fp, nack->ch);
            fputc('\n', stderr);
            refused++;
        }
        return;
    }
    if (code != 0) {
        fprintf(stderr, "proto_session: %s seq %u refused: %d (%s)\n", it2n_msg_name(type), seq, code,
                it2n_proto_strerror(code));
        refused++;
    }
}

/* Feed input, run the link's timers; wait at most max_ms for input. */
static int pump(unsigned max_ms)
{
    uint32_t t = it2n_link_next_timeout(&lk, now_ms());
    if (t > max_ms)
        t = max_ms;
    struct pollfd p = { fd, POLLIN, 0 };
    if (poll(&p, 1, (int)t) < 0 && errno != EINTR)
        return -1;
    /* Read everything waiting before the link's timers run: after a late
     * wake-up (a loaded machine) the answers to frames now due for
     * retransmission may be in the input already; resending those frames
     * would be spurious. Bounded: at most 8 reads of 4 KiB. */
    for (unsigned rd = 0; rd < 8 && (p.revents & POLLIN); rd++) {
        uint8_t buf[4096];
        ssize_t n = read(fd, buf, sizeof buf);
        if (n <= 0)
            break; /* EAGAIN: nothing more now */
        {
            it2n_link_stats b = lk.stats;
            it2n_link_input(&lk, buf, (size_t)n, now_ms());
            if (trace > 2) {
                static it2n_frame_decoder td;
                const uint8_t *q = buf;
                size_t left = (size_t)n;
                while (left) {
                    it2n_frame_hdr fh;
                    const uint8_t *pl = NULL;
                    size_t used = 0;
                    int r = it2n_frame_decode(&td, q, left, &used, &fh, &pl);
                    if (r != 0)
                        fprintf(stderr, "%9.3f frame r %d type %u seq %u flags %x len %u\n",
                                (double)(now_us() - t_start) / 1e3, r, fh.type, fh.seq, fh.flags, fh.len);
                    q += used;
                    left -= used;
                }
            }
            if (trace > 1)
                fprintf(stderr, "%9.3f read %zd: dup %u ahead %u buffered %u gaps %u acks %u stale %u rto %u\n",
                        (double)(now_us() - t_start) / 1e3, n, lk.stats.rx_dup - b.rx_dup,
                        lk.stats.rx_ahead - b.rx_ahead, lk.stats.rx_buffered - b.rx_buffered,
                        lk.stats.tx_gaps - b.tx_gaps, lk.stats.rx_acks - b.rx_acks,
                        lk.stats.rx_stale_acks - b.rx_stale_acks, (unsigned)it2n_link_rto(&lk));
        }
    }
    uint32_t retx0 = lk.stats.tx_retx;
    it2n_link pre_dbg; /* trace 4: the link as it was before a poll that resent */
    if (trace > 3) pre_dbg = lk;
    uint32_t pnow = now_ms();
    it2n_link_poll(&lk, pnow);
    if (trace > 3 && (lk.stats.tx_retx != retx0 || lk.stats.tx_stall_waits != pre_dbg.stats.tx_stall_waits)) {
        fprintf(stderr, "DBG%s now %u rx_last %u heard %u rto %u\n",
                lk.stats.tx_stall_waits != pre_dbg.stats.tx_stall_waits ? " STALLWAIT" : "", pnow, pre_dbg.rx_last, pre_dbg.rx_heard, (unsigned)it2n_link_rto(&pre_dbg));
        for (unsigned k = 0; k < IT2N_PROTO_WINDOW; k++) if (pre_dbg.slot[k].used)
            fprintf(stderr, "DBG  seq %u tries %u tmo %u held %u pw %u dl %d gone %d last %d\n", pre_dbg.slot[k].seq, pre_dbg.slot[k].tries, pre_dbg.slot[k].tmo, pre_dbg.slot[k].held, pre_dbg.slot[k].probe_wait, (int)(pre_dbg.slot[k].deadline - pnow), (int)(pre_dbg.slot[k].gone - pnow), (int)(pre_dbg.slot[k].last - pnow));
    }
    if (trace > 2 && lk.stats.tx_retx != retx0)
        for (unsigned k = 0; k < IT2N_PROTO_WINDOW; k++)
            if (lk.slot[k].used && lk.slot[k].last == now_ms())
                fprintf(stderr, "%9.3f retx seq %u tries %u held %u rto %u\n", (double)(now_us() - t_start) / 1e3,
                        lk.slot[k].seq, lk.slot[k].tries, lk.slot[k].held, (unsigned)it2n_link_rto(&lk));
    return 0;
}

static uint64_t deadline;

static int send_msg(const it2n_msg *m)
{
    int32_t s;
    while ((s = it2n_link_send(&lk, m, now_ms())) == IT2N_PROTO_ERR_BUSY) {
        if (now_us() > deadline || pump(50))
            return -1;
    }
    if (it2n_link_pending(&lk) > max_in_flight)
        max_in_flight = it2n_link_pending(&lk);
    if (s < 0) {
        fprintf(stderr, "proto_session: send %s: %s\n", it2n_msg_name(m->type), it2n_proto_strerror((int)s));
        exit(2);
    }
    return (int)s;
}

/* Send a request and wait until all `want` responses arrived, re-sending
 * it when they stop coming. Returns 0, or -1 on timeout. */
static int request(const it2n_msg *m, uint32_t want)
{
    memset(&cur, 0, sizeof cur);
    cur.msg = *m;
    cur.want = want;
    cur.state = R_SENT;
    cur.seq = send_msg(m);
    if (cur.seq < 0)
        return -1;
    while (cur.got < cur.want) {
        if (now_us() > deadline || refused)
            return -1;
        if (cur.state == R_RESEND) { /* BUSY or lost: back off, ask again */
            uint64_t until = now_us() + 100000u;
            while (now_us() < until)
                pump(20);
            cur.state = R_SENT;
            cur.seq = send_msg(m);
            if (cur.seq < 0)
                return -1;
            continue;
        }
        if (cur.state == R_ACKED && now_us() - cur.progress > (uint64_t)rerequest_ms * 1000u) {
            rereq_timeout++;
            cur.state = R_SENT;
            cur.seq = send_msg(m);
            if (cur.seq < 0)
                return -1;
            continue;
        }
        if (pump(20))
            return -1;
    }
    /* the request's own ACK may still be in flight: let the link settle */
    while (it2n_link_pending(&lk) && now_us() < deadline)
        pump(20);
    cur.state = R_NONE;
    return 0;
}

/* Every QUERY of qq[0..nqq), as many in flight as the window takes (a
 * host has no reason to wait for one result before asking the next
 * question); a query whose result stops coming is asked again (counted,
 * as in request()). Returns 0, or -1 on timeout. */
static int query_all(void)
{
    unsigned next = 0, done = 0;
    while (done < nqq) {
        if (now_us() > deadline || refused)
            return -1;
        for (unsigned k = 0; k < next; k++) {
            int again = qq[k].state == R_RESEND ||
                        (qq[k].state == R_ACKED && !qq[k].got &&
                         now_us() - qq[k].progress > (uint64_t)rerequest_ms * 1000u);
            if (!again || !it2n_link_can_send(&lk))
                continue;
            if (qq[k].state == R_ACKED)
                rereq_timeout++;
            qq[k].state = R_SENT;
            qq[k].seq = it2n_link_send(&lk, &qq[k].msg, now_ms());
        }
        while (next < nqq && it2n_link_can_send(&lk)) {
            qq[next].state = R_SENT;
            qq[next].seq = it2n_link_send(&lk, &qq[next].msg, now_ms());
            if (trace)
                fprintf(stderr, "%9.3f tx QUERY %u seq %d\n", (double)(now_us() - t_start) / 1e3, next,
                        qq[next].seq);
            next++;
        }
        done = 0;
        for (unsigned k = 0; k < nqq; k++)
            done += qq[k].got;
        if (done < nqq && pump(20))
            return -1;
    }
    return 0;
}

static int wait_idle(void)
{
    while (it2n_link_pending(&lk)) {
        if (now_us() > deadline || refused || pump(20))
            return -1;
    }
    return refused ? -1 : 0;
}

/* CONFIGURE is a barrier (docs/protocol.md 4.2 rule 7): sent with nothing
 * else in flight, answered before anything follows. 0 or failure. */
static int configure(const it2n_dataset *d)
{
    it2n_msg c;
    memset(&c, 0, sizeof c);
    c.type = IT2N_MSG_CONFIGURE;
    c.u.configure.model = (uint8_t)model_id;
    c.u.configure.n = d->n;
    c.u.configure.m = d->m;
    c.u.configure.flags = d->flags;
    return wait_idle() || send_msg(&c) < 0 || wait_idle();
}

/* Queue PUTs of every entry (flags), keeping the window full. */
static int put_all(uint8_t flags, unsigned *entries)
{
    it2n_msg m;
    unsigned i = 0, j = 0, fp = 0;
    for (;;) {
        memset(&m, 0, sizeof m);
        m.type = IT2N_MSG_PUT;
        m.u.put.model = (uint8_t)model_id;
        m.u.put.flags = flags;
        while (i <= ds.n && m.u.put.count < IT2N_PUT_MAX) {
            if (ds.present[i][j] & (1u << fp)) {
                it2n_put_entry *e = &m.u.put.e[m.u.put.count++];
                e->i = (uint8_t)i;
                e->j = (uint8_t)j;
                e->fp = (uint8_t)fp;
                it2n_dataset_get(&ds, i, j, fp, e->vals);
            }
            if (++fp == IT2N_FP_COUNT) {
                fp = 0;
                if (++j > ds.m) {
                    j = 0;
                    i++;
                }
            }
        }
        if (m.u.put.count == 0)
            return 0;
        int s = send_msg(&m);
        if (s < 0 || refused)
            return -1;
        put_entries_in_flight[s] = m.u.put.count;
        *entries += m.u.put.count;
    }
}

static int open_device(const char *path)
{
    struct termios t;
    fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (fd < 0)
        return -1;
    if (tcgetattr(fd, &t) == 0) {
        cfmakeraw(&t);
        tcsetattr(fd, TCSANOW, &t);
    }
    return 0;
}

int main(int argc, char **argv)
{
    const char *dev = NULL;
    unsigned n = 7, mdeg = 7, queries = 16, sample = 33, ingest = 0, rto = 0, baud = 0, tries = 100, timeout_s = 300;
    unsigned window = 4, reconfigure = 0, version = IT2N_PROTO_VERSION;
    int in_fd = -1;
    uint32_t seed = 2026;
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!v) {
            fprintf(stderr, "proto_session: %s needs a value\n", a);
            return 2;
        }
        k++;
        if (!strcmp(a, "--device")) dev = v;
        else if (!strcmp(a, "--fd")) in_fd = atoi(v);
        else if (!strcmp(a, "--reconfigure")) reconfigure = (unsigned)atoi(v);
        else if (!strcmp(a, "--window")) window = (unsigned)atoi(v);
        else if (!strcmp(a, "--version")) version = (unsigned)atoi(v);
        else if (!strcmp(a, "--degree")) {
            if (sscanf(v, "%ux%u", &n, &mdeg) != 2) {
                fprintf(stderr, "proto_session: --degree NxM\n");
                return 2;
            }
        } else if (!strcmp(a, "--queries")) queries = (unsigned)atoi(v);
        else if (!strcmp(a, "--sample")) sample = (unsigned)atoi(v);
        else if (!strcmp(a, "--ingest")) ingest = (unsigned)atoi(v);
        else if (!strcmp(a, "--rto")) rto = (unsigned)atoi(v);
        else if (!strcmp(a, "--baud")) baud = (unsigned)atoi(v);
        else if (!strcmp(a, "--tries")) tries = (unsigned)atoi(v);
        else if (!strcmp(a, "--rerequest-ms")) rerequest_ms = (unsigned)atoi(v);
        else if (!strcmp(a, "--timeout")) timeout_s = (unsigned)atoi(v);
        else if (!strcmp(a, "--seed")) seed = (uint32_t)strtoul(v, NULL, 0);
        else if (!strcmp(a, "--model")) model_id = (unsigned)atoi(v);
        else {
            fprintf(stderr, "proto_session: unknown option %s\n", a);
            return 2;
        }
    }
    if ((!dev) == (in_fd < 0) || window < IT2N_PROTO_WINDOW_MIN || window > IT2N_PROTO_WINDOW ||
        (window & (window - 1)) || n < 1 || n > IT2N_MAX_DEGREE || mdeg < 1 || mdeg > IT2N_MAX_DEGREE ||
        queries > MAX_QUERIES || (sample && (sample < 2 || sample * sample > MAX_NODES)) ||
        tries < 1 || tries > 255 || model_id > 254 ||
        (version != IT2N_PROTO_VERSION && version != IT2N_PROTO_VERSION_12)) {
        fprintf(stderr, "usage: proto_session --device PATH | --fd N [--degree NxM] [--queries Q<=%u] [--sample S]\n"
                        "       [--ingest ROUNDS] [--window 4..%u] [--baud BD] [--rto MS] [--tries N]\n"
                        "       [--rerequest-ms MS] [--timeout S] [--version 2|3]\n",
                MAX_QUERIES, (unsigned)IT2N_PROTO_WINDOW);
        return 2;
    }
    it2n_errinfo e;
    if (synth_dataset(&ds, n, mdeg, IT2N_F_Z, seed, &e) != IT2N_OK) {
        fprintf(stderr, "proto_session: synth_dataset failed (%d)\n", e.code);
        return 2;
    }
    it2n_model_init(&local);
    if (it2n_model_solve(&local, &ds, &e) != IT2N_OK) {
        fprintf(stderr, "proto_session: local solve failed (%d)\n", e.code);
        return 2;
    }
    sample_seen = calloc(MAX_NODES, 1);
    sample_v = calloc(MAX_NODES, sizeof *sample_v);
    if (in_fd >= 0) {
        struct termios t;
        fd = in_fd;
        if (fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK) < 0) {
            perror("proto_session: --fd");
            return 3;
        }
        if (tcgetattr(fd, &t) == 0) {
            cfmakeraw(&t);
            tcsetattr(fd, TCSANOW, &t);
        }
    }
    if (!sample_seen || !sample_v || (in_fd < 0 && open_device(dev))) {
        perror("proto_session: open");
        return 3;
    }
    static it2n_ostream os = { fd_write, NULL };
    it2n_link_cfg cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.out = &os;
    cfg.on_rx = on_rx;
    cfg.on_done = on_done;
    /* The line's baud rate (0 = unknown): the RTO then counts from when a
     * frame has left the line, default it2n_link_rto_default (as it2nd). */
    cfg.baud = baud;
    cfg.rto_ms = rto ? rto : baud ? it2n_link_rto_default(baud) : 150u;
    cfg.max_tries = (uint8_t)tries;
    cfg.window = (uint8_t)window;
    cfg.first_seq = (uint16_t)((now_us() ^ ((uint64_t)getpid() << 8)) & 0xFFFF);
    /* --version 3: a v1.2 client (the daemon hands out the session) */
    cfg.version = (uint8_t)version;
    /* A v1.1 session id (protocol.md 4.2): without one (0) every SYN copy
     * starts a new sequence, so a late duplicate of the first frame would
     * reset the daemon's receiver in the middle of the session. */
    {
        uint32_t rnd = 0;
        if (getrandom(&rnd, sizeof rnd, GRND_NONBLOCK) != (ssize_t)sizeof rnd)
            rnd = (uint32_t)(now_us() * 2654435761u) ^ (uint32_t)getpid();
        cfg.session = rnd ? rnd : 1u;
    }
    if (it2n_link_init(&lk, &cfg) != IT2N_OK)
        return 2;

    trace = getenv("PROTO_SESSION_TRACE") ? atoi(getenv("PROTO_SESSION_TRACE")) : 0; /* 2: every read */
    t_start = now_us();
    uint64_t t0 = now_us(), t_put0 = 0, t_put1 = 0, t_upload = 0, t_queries = 0;
    deadline = t0 + (uint64_t)timeout_s * 1000000u;
    unsigned entries = 0;
    int ok = 0;
    it2n_msg m;
    do {
        memset(&m, 0, sizeof m);
        m.type = IT2N_MSG_HELLO;
        m.u.hello.version_min = version == IT2N_PROTO_VERSION_12 ? IT2N_PROTO_VERSION_12 : 1;
        m.u.hello.version_max = (uint8_t)version;
        m.u.hello.max_degree = IT2N_MAX_DEGREE;
        m.u.hello.window = it2n_link_window(&lk);
        m.u.hello.caps = IT2N_CAP_INSTRUMENT;
        m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
        m.u.hello.max_models = 1;
        memcpy(m.u.hello.node, "proto-bench", 11);
        if (send_msg(&m) < 0 || wait_idle())
            break;
        if (configure(&ds))
            break;
        t_put0 = now_us();
        for (unsigned r = 0; r < (ingest ? ingest : 1); r++) {
            if (ingest && reconfigure && r > 0 && configure(&ds))
                goto out;
            if (put_all(ingest && !reconfigure ? IT2N_PUT_REPLACE : 0, &entries))
                goto out;
        }
        if (wait_idle())
            break;
        t_put1 = now_us();
        memset(&m, 0, sizeof m);
        m.type = IT2N_MSG_COMMIT;
        m.u.model.model = (uint8_t)model_id;
        if (send_msg(&m) < 0 || wait_idle())
            break;
        t_upload = now_us();
        if (!ingest) {
            for (query_k = 0; query_k < queries; query_k++) {
                /* a 4-wide lattice of interior parameters, then its shifts */
                unsigned a = query_k % 4, b = (query_k / 4) % 4, c = query_k / 16;
                memset(&qq[query_k], 0, sizeof qq[query_k]);
                m = (it2n_msg){0};
                m.type = IT2N_MSG_QUERY;
                m.u.query.model = (uint8_t)model_id;
                m.u.query.u = (uint32_t)(((uint64_t)(2 * a + 1) * IT2N_WIRE_PAR_ONE) / 8u) + c;
                m.u.query.w = (uint32_t)(((uint64_t)(2 * b + 1) * IT2N_WIRE_PAR_ONE) / 8u) + c;
                qq[query_k].msg = m;
            }
            nqq = queries;
            if (query_all())
                goto out;
            for (query_k = 0; query_k < queries; query_k++) {
                fold(&qres[query_k].out_of_range, sizeof qres[query_k].out_of_range);
                fold(qres[query_k].v, sizeof qres[query_k].v);
                fold(&qres[query_k].sum, sizeof qres[query_k].sum);
            }
            t_queries = now_us();
            if (sample) {
                memset(&m, 0, sizeof m);
                m.type = IT2N_MSG_SAMPLE;
                m.u.sample.model = (uint8_t)model_id;
                m.u.sample.fp = IT2N_FP_D;
                m.u.sample.rows = m.u.sample.cols = (uint16_t)sample;
                if (request(&m, sample * sample))
                    goto out;
                fold(sample_v, (size_t)sample * sample * sizeof *sample_v);
            }
        }
        ok = 1;
    } while (0);
out:;
    uint64_t t1 = now_us();
    double wall = (double)(t1 - t0) / 1e6;
    int rc = !ok ? (refused ? 1 : 3) : (mismatches || dup_diff) ? 1 : 0;
    printf("{\"ok\": %s, \"exit\": %d, \"wall_s\": %.6f, \"upload_s\": %.6f, \"queries_s\": %.6f, "
           "\"sample_s\": %.6f, \"degree\": [%u, %u], \"entries\": %u, \"queries\": %u, \"sample\": %u, "
           "\"ingest_rounds\": %u, \"put_s\": %.6f, \"entries_per_s\": %.1f, \"entries_acked\": %u, "
           "\"digest\": \"%016llx\", \"mismatches\": %u, \"duplicate_points_differing\": %u, \"refused\": %u, "
           "\"host_rerequests\": %u, \"rerequests_stalled\": %u, \"rerequests_busy\": %u, "
           "\"rerequests_lost\": %u, \"busy_retries\": %u, \"link\": {\"tx_frames\": %u, \"tx_retx\": %u, \"tx_timeouts\": %u, "
           "\"rx_delivered\": %u, \"rx_dup\": %u, \"rx_ahead\": %u, \"rx_nosync\": %u, \"tx_fast_retx\": %u, "
           "\"tx_resyncs\": %u, \"rx_stale_acks\": %u, \"tx_stall_waits\": %u}, \"window\": %u, \"version\": %u, "
           "\"daemon_window\": %u, \"max_in_flight\": %u, \"rto_ms\": %u}\n",
           rc == 0 ? "true" : "false", rc, wall, t_upload ? (double)(t_upload - t0) / 1e6 : 0.0,
           t_queries ? (double)(t_queries - t_upload) / 1e6 : 0.0,
           t_queries && ok ? (double)(t1 - t_queries) / 1e6 : 0.0, ds.n, ds.m, entries, queries, sample,
           ingest, t_put1 ? (double)(t_put1 - t_put0) / 1e6 : 0.0,
           t_put1 > t_put0 ? (double)ack_entries / ((double)(t_put1 - t_put0) / 1e6) : 0.0, ack_entries,
           (unsigned long long)digest, mismatches, dup_diff, refused,
           rereq_timeout + rereq_busy + rereq_lost, rereq_timeout, rereq_busy, rereq_lost,
           busy_retries, lk.stats.tx_frames, lk.stats.tx_retx, lk.stats.tx_timeouts, lk.stats.rx_delivered,
           lk.stats.rx_dup, lk.stats.rx_ahead, lk.stats.rx_nosync, lk.stats.tx_fast_retx, lk.stats.tx_resyncs,
           lk.stats.rx_stale_acks, lk.stats.tx_stall_waits, window, version, daemon_window, max_in_flight, (unsigned)it2n_link_rto(&lk));
    return rc;
}
