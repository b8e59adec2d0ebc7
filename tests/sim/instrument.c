/*
 * instrument — simulated instrument for the daemon's end-to-end tests:
 * streams a CSV data set as HELLO, CONFIGURE, PUT batches and COMMIT with
 * the protocol/ reliable link, over its own pty (the daemon opens the
 * slave through a symlink, like /dev/serial/by-id/...), with faults:
 *
 *   instrument --link PATH --csv FILE [--model ID] [--batch K] [--replace]
 *              [--garbage PCT] [--drop PCT] [--dup PCT] [--seed S]
 *              [--hangup-after N] [--ack-log FILE] [--timeout S] [--no-configure]
 *              [--v11] [--session ID] [--first-seq N]
 *
 *   protocol v1.2 by default: the daemon hands out the session id (HELLO
 *   with session 0); --v11 speaks v1.1 with a session id of its own
 *   (random, or --session ID: a fixed one, as a board without entropy
 *   has). --first-seq N fixes the first sequence number (default random).
 *
 *   --garbage  PCT of frames preceded by random bytes (and a delimiter)
 *   --drop     PCT of frames never written (the link retransmits)
 *   --dup      PCT of frames written twice (the receiver must apply once)
 *   --hangup-after N  close the pty once N entries are ACKed (exit 4)
 *   --ack-log  after every ACKed PUT, the total of ACKed entries (a line)
 *   --events FILE  act as a passive peer instead: HELLO (caps EVENTS), then
 *              append every EVENT received to FILE as "model kind code
 *              generation" (flushed per line) until --timeout (exit 0)
 *   --sample FP ROWS COLS, --net FP, --query U W: after COMMIT, act as a
 *              host and check the daemon's SAMPLE_DATA / NET_ROW /
 *              QUERY_RESULT bit for bit against the core's own solve
 * Exit: 0 everything ACKed, 1 NACK, 2 usage/data, 3 timeout/I-O, 4 hang-up.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "it2n_link.h"
#include "simcommon.h"

static int master = -1;
static unsigned pct_garbage, pct_drop, pct_dup;
static uint32_t rng = 12345;
static uint8_t frame[IT2N_FRAME_MAX_WIRE + 16];
static size_t flen;
static FILE *acklog;
static unsigned acked, nack_code_seen;
static uint8_t put_count[65536];
static FILE *evlog;

static uint32_t rnd(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return rng;
}

static uint32_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u);
}

static void raw_write(const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t w = write(master, p, n);
        if (w < 0 && (errno == EAGAIN || errno == EINTR)) {
            usleep(1000);
            continue;
        }
        if (w <= 0)
            return;
        p += w;
        n -= (size_t)w;
    }
}

/* Collect a whole frame (ends with 0x00), then apply the faults. */
static int os_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    (void)s;
    if (flen + len > sizeof frame)
        flen = 0;
    memcpy(frame + flen, buf, len);
    flen += len;
    if (frame[flen - 1] != 0)
        return 0;
    if (rnd() % 100 < pct_garbage) {
        uint8_t g[24];
        size_t n = 1 + rnd() % 20;
        for (size_t k = 0; k < n; k++)
            g[k] = (uint8_t)(1 + rnd() % 255);
        g[n] = 0;
        raw_write(g, n + 1);
    }
    if (rnd() % 100 >= pct_drop) {
        raw_write(frame, flen);
        if (rnd() % 100 < pct_dup)
            raw_write(frame, flen);
    }
    flen = 0;
    return 0;
}

/* Host-side checks of the daemon's responses against a local solve. */
static it2n_model local;
static unsigned got_points, got_rows, got_results, mismatches;
/* The daemon's HELLO: its caps say whether PUT FINE (Q30 memberships,
 * protocol v1.3) may be sent. */
static int peer_hello;
static uint32_t peer_caps;

static int on_rx(void *app, uint16_t seq, const it2n_msg *msg)
{
    (void)app;
    (void)seq;
    if (msg->type == IT2N_MSG_HELLO) {
        peer_hello = 1;
        peer_caps = msg->u.hello.caps;
    } else if (msg->type == IT2N_MSG_EVENT && evlog) {
        fprintf(evlog, "%u %u %d %u\n", msg->u.event.model, msg->u.event.kind, msg->u.event.code,
                (unsigned)msg->u.event.generation);
        fflush(evlog);
    } else if (msg->type == IT2N_MSG_SAMPLE_DATA) {
        const it2n_msg_sample_data *d = &msg->u.sample_data;
        for (unsigned k = 0; k < d->count; k++) {
            uint32_t idx = d->start + k, r = idx / d->cols, c = idx % d->cols;
            it2n_point pt;
            it2n_eval(&local, (it2n_par)(((uint64_t)r << IT2N_PAR_FRAC) / (d->rows - 1u)),
                      (it2n_par)(((uint64_t)c << IT2N_PAR_FRAC) / (d->cols - 1u)), &pt, NULL);
            mismatches += memcmp(pt.v[d->fp], d->v[k], sizeof d->v[k]) != 0;
            got_points++;
        }
    } else if (msg->type == IT2N_MSG_NET_ROW) {
        const it2n_msg_net_row *d = &msg->u.net_row;
        for (unsigned j = 0; j <= d->m; j++)
            for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++)
                mismatches += it2n_model_ctrl(&local, d->row, j, d->fp, ch) != d->v[j][ch];
        got_rows++;
    } else if (msg->type == IT2N_MSG_QUERY_RESULT) {
        const it2n_msg_query_result *d = &msg->u.query_result;
        it2n_point pt;
        it2n_eval(&local, it2n_par_from_wire(d->u), it2n_par_from_wire(d->w), &pt, NULL);
        mismatches += memcmp(pt.v, d->v, sizeof pt.v) != 0;
        mismatches += memcmp(&pt.sum, &d->sum, sizeof pt.sum) != 0;
        got_results++;
    }
    return 0; /* the daemon's HELLO and responses: ACK */
}

static int failed;

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack)
{
    (void)app;
    if (code == 0) {
        if (type == IT2N_MSG_PUT) {
            acked += put_count[seq];
            if (acklog) {
                fprintf(acklog, "%u\n", acked);
                fflush(acklog);
            }
        }
        return;
    }
    fprintf(stderr, "instrument: %s seq %u refused: %d (%s)", it2n_msg_name(type), seq, code,
            it2n_proto_strerror(code));
    if (nack)
        fprintf(stderr, " at i %d j %d fp %d ch %d", nack->i, nack->j, nack->fp, nack->ch);
    fputc('\n', stderr);
    nack_code_seen = 1;
    failed = code == IT2N_PROTO_ERR_TIMEOUT ? 3 : 1;
}

/* The symlink goes away with the process, as a USB serial device does on
 * unplug: a stale link would point at a pts number the kernel hands to the
 * next pty, and the daemon would open someone else's line. */
static const char *link_name;
static char pty_name[128];

/* Only our own link: a newer instrument may have replaced it already.
 * (readlink and unlink are async-signal-safe.) */
static void unlink_link(void)
{
    char target[sizeof pty_name];
    ssize_t n = link_name ? readlink(link_name, target, sizeof target - 1) : -1;
    if (n > 0) {
        target[n] = 0;
        if (!strcmp(target, pty_name))
            unlink(link_name);
    }
}

static void on_term(int sig)
{
    (void)sig;
    unlink_link();
    _exit(0);
}

static int make_link(const char *path)
{
    char name[128], tmp[512];
    int slave;
    struct termios t;
    if (openpty(&master, &slave, name, NULL, NULL))
        return -1;
    tcgetattr(slave, &t);
    cfmakeraw(&t);
    tcsetattr(slave, TCSANOW, &t);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    unlink(tmp);
    if (symlink(name, tmp) || rename(tmp, path))
        return -1;
    link_name = path;
    snprintf(pty_name, sizeof pty_name, "%s", name);
    atexit(unlink_link);
    signal(SIGTERM, on_term);
    signal(SIGINT, on_term);
    /* slave stays open: the master then never reports a hang-up while the
     * daemon is between opens. */
    return 0;
}

int main(int argc, char **argv)
{
    const char *link_path = NULL, *csv = NULL;
    unsigned model = 1, batch = 4, replace = 0, hangup_after = 0, timeout_s = 30, configure = 1, v11 = 0;
    long session = -1, first_seq = -1;
    int sample_fp = -1, net_fp = -1, want_query = 0;
    unsigned sample_rows = 0, sample_cols = 0;
    it2n_par qu = 0, qw = 0;
    static it2n_dataset ds;
    static it2n_link l;
    it2n_ostream os = { os_write, NULL };
    it2n_link_cfg cfg;
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!strcmp(a, "--replace")) { replace = 1; continue; }
        if (!strcmp(a, "--no-configure")) { configure = 0; continue; }
        if (!strcmp(a, "--v11")) { v11 = 1; continue; }
        if (!strcmp(a, "--sample") && k + 3 < argc) {
            sample_fp = atoi(argv[k + 1]);
            sample_rows = (unsigned)atoi(argv[k + 2]);
            sample_cols = (unsigned)atoi(argv[k + 3]);
            k += 3;
            continue;
        }
        if (!strcmp(a, "--query") && k + 2 < argc) {
            if (it2n_parse_par(argv[k + 1], strlen(argv[k + 1]), &qu) || it2n_parse_par(argv[k + 2], strlen(argv[k + 2]), &qw))
                return 2;
            want_query = 1;
            k += 2;
            continue;
        }
        if (!v) { fprintf(stderr, "instrument: %s needs a value\n", a); return 2; }
        k++;
        if (!strcmp(a, "--link")) link_path = v;
        else if (!strcmp(a, "--csv")) csv = v;
        else if (!strcmp(a, "--model")) model = (unsigned)atoi(v);
        else if (!strcmp(a, "--batch")) batch = (unsigned)atoi(v);
        else if (!strcmp(a, "--garbage")) pct_garbage = (unsigned)atoi(v);
        else if (!strcmp(a, "--drop")) pct_drop = (unsigned)atoi(v);
        else if (!strcmp(a, "--dup")) pct_dup = (unsigned)atoi(v);
        else if (!strcmp(a, "--seed")) rng = (uint32_t)strtoul(v, NULL, 0) | 1u;
        else if (!strcmp(a, "--hangup-after")) hangup_after = (unsigned)atoi(v);
        else if (!strcmp(a, "--timeout")) timeout_s = (unsigned)atoi(v);
        else if (!strcmp(a, "--ack-log")) acklog = fopen(v, "w");
        else if (!strcmp(a, "--net")) net_fp = atoi(v);
        else if (!strcmp(a, "--events")) evlog = fopen(v, "a");
        else if (!strcmp(a, "--session")) session = (long)(strtoul(v, NULL, 0) & 0xFFFFFFFFul);
        else if (!strcmp(a, "--first-seq")) first_seq = (long)(strtoul(v, NULL, 0) & 0xFFFFul);
        else { fprintf(stderr, "instrument: unknown option %s\n", a); return 2; }
    }
    if (!link_path || (!csv && !evlog) || batch < 1 || batch > IT2N_PUT_MAX)
        return 2;
    if (csv) /* kept as read (memberships in Q30): what PUT FINE carries */
        sim_load_csv(csv, 0, &ds);
    {
        it2n_errinfo e;
        it2n_model_init(&local);
        if (it2n_model_solve(&local, &ds, &e) != IT2N_OK && (sample_fp >= 0 || net_fp >= 0 || want_query)) {
            fprintf(stderr, "instrument: local solve failed\n");
            return 2;
        }
    }
    if (make_link(link_path)) {
        perror("instrument: pty");
        return 3;
    }
    memset(&cfg, 0, sizeof cfg);
    cfg.out = &os;
    cfg.on_rx = on_rx;
    cfg.on_done = on_done;
    cfg.rto_ms = 150;
    cfg.max_tries = 100;
    cfg.first_seq = (uint16_t)(rnd() & 0xFFFF);
    cfg.session = (rnd() ^ now_ms() ^ ((uint32_t)getpid() << 12)) | 1u; /* v1.1: new per run, never 0 */
    if (first_seq >= 0)
        cfg.first_seq = (uint16_t)first_seq;
    if (session >= 0)
        cfg.session = (uint32_t)session;
    cfg.version = v11 ? 0 : IT2N_PROTO_VERSION_12; /* v1.2: the daemon's id */
    it2n_link_init(&l, &cfg);

    /* v1.2: HELLO first in any case (it brings the session); v1.1 without
     * CONFIGURE starts with the PUTs (HELLO is optional there) */
    unsigned step = configure || !v11 ? 0 : 2, i = 0, j = 0, fp = 0, hello_sent = 0;
    uint32_t start = now_ms();
    while (!failed) {
        uint32_t now = now_ms();
        it2n_msg m;
        if (now - start > timeout_s * 1000u && evlog)
            return 0; /* passive peer: listened for the time given */
        if (now - start > timeout_s * 1000u) {
            fprintf(stderr, "instrument: timeout, %u entries ACKed\n", acked);
            return 3;
        }
        /* After the stream: the host requests, one at a time. */
        /* Each request waits for the previous one's responses. */
        int prev_done = (step <= 4 || got_points >= (sample_fp >= 0 ? sample_rows * sample_cols : 0)) &&
                        (step <= 5 || got_rows >= (net_fp >= 0 ? ds.n + 1u : 0));
        if (step >= 4 && step < 7 && it2n_link_pending(&l) == 0 && prev_done) {
            memset(&m, 0, sizeof m);
            if (step == 4 && sample_fp >= 0) {
                m.type = IT2N_MSG_SAMPLE;
                m.u.sample.model = (uint8_t)model;
                m.u.sample.fp = (uint8_t)sample_fp;
                m.u.sample.rows = (uint16_t)sample_rows;
                m.u.sample.cols = (uint16_t)sample_cols;
            } else if (step == 5 && net_fp >= 0) {
                m.type = IT2N_MSG_GET_NET;
                m.u.get_net.model = (uint8_t)model;
                m.u.get_net.fp = (uint8_t)net_fp;
            } else if (step == 6 && want_query) {
                m.type = IT2N_MSG_QUERY;
                m.u.query.model = (uint8_t)model;
                m.u.query.u = it2n_par_to_wire(qu);
                m.u.query.w = it2n_par_to_wire(qw);
            }
            step++;
            if (m.type && it2n_link_send(&l, &m, now) < 0)
                return 2;
        }
        /* CONFIGURE is a barrier (docs/protocol.md 4.2 rule 7): alone in
         * flight, answered before the first PUT goes out. */
        /* the first PUT waits for the daemon's HELLO (if ours went out):
         * its caps decide the membership format */
        while (step < 4 && (step == 0 || it2n_link_can_send(&l)) &&
               !(step == 2 && hello_sent && !peer_hello) &&
               ((step != 1 && !(step == 2 && i == 0 && j == 0 && fp == 0)) || it2n_link_pending(&l) == 0)) {
            memset(&m, 0, sizeof m);
            if (step == 0) {
                m.type = IT2N_MSG_HELLO;
                m.u.hello.version_min = m.u.hello.version_max =
                    v11 ? IT2N_PROTO_VERSION : IT2N_PROTO_VERSION_12;
                m.u.hello.max_degree = IT2N_MAX_DEGREE;
                m.u.hello.window = it2n_link_window(&l);
                m.u.hello.caps = evlog ? IT2N_CAP_EVENTS : IT2N_CAP_INSTRUMENT;
                m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
                m.u.hello.max_models = 1;
                memcpy(m.u.hello.node, evlog ? "sim-peer" : "sim-instrument", evlog ? 8 : 14);
                step = evlog ? 100 : configure ? 1 : 2;
                hello_sent = 1;
            } else if (step == 1) {
                m.type = IT2N_MSG_CONFIGURE;
                m.u.configure.model = (uint8_t)model;
                m.u.configure.n = ds.n;
                m.u.configure.m = ds.m;
                m.u.configure.flags = ds.flags;
                step = 2;
            } else if (step == 2) {
                m.type = IT2N_MSG_PUT;
                m.u.put.model = (uint8_t)model;
                m.u.put.flags = (uint8_t)((replace ? IT2N_PUT_REPLACE : 0u) |
                                          ((peer_caps & IT2N_CAP_FINE) ? IT2N_PUT_FINE : 0u));
                while (i <= ds.n && m.u.put.count < batch) {
                    if (ds.present[i][j] & (1u << fp)) {
                        it2n_put_entry *e = &m.u.put.e[m.u.put.count++];
                        e->i = (uint8_t)i;
                        e->j = (uint8_t)j;
                        e->fp = (uint8_t)fp;
                        it2n_dataset_get_fine(&ds, i, j, fp, e->vals);
                        if (!(m.u.put.flags & IT2N_PUT_FINE)) {
                            /* a daemon without FINE: Q24 only if exact */
                            for (unsigned ch = IT2N_CH_T; ch <= IT2N_CH_F; ch++) {
                                if (e->vals[ch] % 64 != 0) {
                                    fprintf(stderr, "instrument: (%u,%u,%u): a membership finer than "
                                                    "2^-24 and the daemon did not announce FINE\n",
                                            i, j, fp);
                                    return 2;
                                }
                                e->vals[ch] /= 64;
                            }
                        }
                    }
                    if (++fp == IT2N_FP_COUNT) {
                        fp = 0;
                        if (++j > ds.m) {
                            j = 0;
                            i++;
                        }
                    }
                }
                if (m.u.put.count == 0) {
                    step = 3;
                    continue;
                }
            } else {
                m.type = IT2N_MSG_COMMIT;
                m.u.model.model = (uint8_t)model;
                step = 4;
            }
            int32_t seq = it2n_link_send(&l, &m, now);
            if (seq < 0) {
                fprintf(stderr, "instrument: send: %s\n", it2n_proto_strerror((int)seq));
                return 2;
            }
            if (m.type == IT2N_MSG_PUT)
                put_count[seq] = m.u.put.count;
        }
        if (step >= 7 && step < 100 && it2n_link_pending(&l) == 0 &&
            got_points >= (sample_fp >= 0 ? sample_rows * sample_cols : 0) &&
            got_rows >= (net_fp >= 0 ? ds.n + 1u : 0) && got_results >= (unsigned)want_query)
            break;
        if (hangup_after && acked >= hangup_after) {
            close(master);
            printf("instrument: hung up after %u ACKed entries\n", acked);
            return 4;
        }
        struct pollfd p = { master, POLLIN, 0 };
        uint32_t to = it2n_link_next_timeout(&l, now);
        poll(&p, 1, to > 50 ? 50 : (int)to);
        uint8_t buf[2048];
        ssize_t n = read(master, buf, sizeof buf);
        if (n > 0)
            it2n_link_input(&l, buf, (size_t)n, now_ms());
        it2n_link_poll(&l, now_ms());
    }
    if (failed)
        return failed;
    printf("instrument: %s streamed, %u entries ACKed, link: %u frames, %u retransmitted\n", csv, acked,
           l.stats.tx_frames, l.stats.tx_retx);
    if (sample_fp >= 0 || net_fp >= 0 || want_query)
        printf("instrument: host checks: %u sample points, %u net rows, %u query results, %u mismatches\n",
               got_points, got_rows, got_results, mismatches);
    return mismatches ? 1 : 0;
}
