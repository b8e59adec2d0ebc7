/*
 * daemon_link — protocol v1.1 against the real it2nd over a pty (issue 11).
 * The test is the instrument/host on the pty master; the daemon opens the
 * slave through a symlink as it would /dev/serial/by-id/... Scenarios:
 *
 *   sessions N   N back-to-back sessions on one open link, each a new
 *                peer session (new session id) whose first sequence number
 *                is deliberately inside the daemon's duplicate history
 *                (the last W numbers of the previous session). Each
 *                session: HELLO, CONFIGURE, PUT (its own values), COMMIT,
 *                QUERY at both corners, checked against a local solve.
 *                Must end with 0 lost, 0 refused.
 *   kill K       an upload of a 7x7 model, the daemon killed with SIGKILL
 *                K times while PUTs are in flight (delivery unknown) and
 *                restarted; the same link context re-sends: every PUT is
 *                ACKed exactly once (identical entries are an idempotent
 *                success), 0 NACKs, and the solved model equals the local
 *                solve.
 *   wide R       the window negotiated per peer: a peer of window W (the
 *                host build's) uploads a 7x7 model R times keeping W PUTs
 *                in flight (the daemon holds W ACKs for its WAL and sends
 *                every one), then defers its answers to a SAMPLE run: the
 *                daemon keeps min(W, what its RTO covers) frames in
 *                flight; the same with a 4-frame peer (an MCU build):
 *                never more than 4 either way. Run with rto_ms = 300.
 *   lossy PCT    HELLO, upload, COMMIT, 16 QUERYs and a 33x33 SAMPLE with
 *                PCT % drop, duplicate, reorder and corruption of frames in
 *                each direction: every response must arrive without the
 *                host asking twice (0 re-requests) and match the core.
 *   reboot N     N boots of a deterministic v1.2 instrument (the same first
 *                sequence number every boot, no id of its own) on one open
 *                line, killed at random points (during HELLO, STATUS,
 *                CONFIGURE, PUTs, COMMIT, QUERYs), alternating two data
 *                sets; half the kills leave the dying boot's last frames to
 *                arrive after the next boot's HELLO (a relay's buffer), and
 *                the daemon's frames for the dead boot reach the next one.
 *                Each boot asks STATUS before its CONFIGURE: every entry the
 *                previous boot got ACKed is still there (0 lost); a boot
 *                that completes gets every PUT ACKed (no DUPLICATE: 0 stale
 *                entries) and QUERY results equal to its own solve; every
 *                HELLO is answered within one exchange plus 2 RTO.
 *   relimit 1    v1.2: a peer announcing max_payload 64, the daemon killed
 *                and restarted: the peer's link sends its HELLO again by
 *                itself (NACK SESSION) and the SAMPLE_DATA frames after
 *                the restart still hold 1 point (the limit is not lost).
 *   lossy12 PCT  the lossy scenario with a v1.2 peer.
 *   kill12 K     the kill scenario with a v1.2 peer (its frames in flight
 *                re-sent in the session it asks for after each restart).
 *   rebootlossy N  the same with 5 % drop, duplication, reordering and
 *                corruption of frames each way (the HELLO bound is then
 *                not checked: a lost HELLO waits for its retransmission).
 *   reboot11 N   the same with the v1.1 handshake and a fixed session id
 *                (what such an instrument has): asserts that it FAILS
 *                (frames taken for the previous boot's, stalls), which is
 *                what v1.2 fixes.
 *
 * Usage: daemon_link IT2ND SCENARIO ARG [SCENARIO ARG ...]
 * Environment: LINK_EXTRA and DAEMON_EXTRA, lines added to it2nd.conf's
 * [link:inst] and [daemon] sections (e.g. DAEMON_EXTRA='io = epoll').
 * Prints one line of figures per scenario; exit 0 when all held. A stalled
 * reboot prints what it waited for and the daemon log's tail at once.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "it2n_link.h"
#include "synth.h"

#define W IT2N_PROTO_WINDOW

static const char *it2nd;
static char dir[256], conf_path[320], link_path[320], log_path[320];
static int master = -1, slave = -1;
static pid_t dpid = -1;
static uint64_t rng = 0x11AB5EEDu;
static int failures;

static uint32_t rnd(void)
{
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return (uint32_t)((rng * 0x2545F4914F6CDD1Dull) >> 32);
}

static uint32_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u);
}

#define CHECK(c, ...)                                                                              \
    do {                                                                                           \
        if (!(c)) {                                                                                \
            fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);                                   \
            fprintf(stderr, __VA_ARGS__);                                                          \
            fprintf(stderr, "\n");                                                                 \
            failures++;                                                                            \
        }                                                                                          \
    } while (0)

/* ---- the daemon ------------------------------------------------------- */

static void daemon_start(void)
{
    dpid = fork();
    if (dpid == 0) {
        int fd = open(log_path, O_WRONLY | O_CREAT | O_APPEND, 0644);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        close(master);
        close(slave);
        execl(it2nd, it2nd, "-c", conf_path, "-f", "-v", (char *)NULL);
        _exit(127);
    }
}

static void daemon_kill(int sig)
{
    int st;
    if (dpid > 0) {
        kill(dpid, sig);
        waitpid(dpid, &st, 0);
    }
    dpid = -1;
}

static void cleanup(void)
{
    char cmd[600];
    daemon_kill(SIGTERM);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (getenv("KEEP") == NULL && system(cmd) != 0)
        fprintf(stderr, "cleanup failed\n");
}

static void setup(const char *extra)
{
    char name[128];
    struct termios t;
    FILE *f;
    snprintf(dir, sizeof dir, "/tmp/it2n-dlink.XXXXXX");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        exit(2);
    }
    snprintf(conf_path, sizeof conf_path, "%s/it2nd.conf", dir);
    snprintf(link_path, sizeof link_path, "%s/inst0", dir);
    snprintf(log_path, sizeof log_path, "%s/daemon.log", dir);
    if (openpty(&master, &slave, name, NULL, NULL)) {
        perror("openpty");
        exit(2);
    }
    tcgetattr(slave, &t);
    cfmakeraw(&t);
    tcsetattr(slave, TCSANOW, &t);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    if (symlink(name, link_path)) {
        perror("symlink");
        exit(2);
    }
    f = fopen(conf_path, "w");
    fprintf(f, "[daemon]\nstate_dir = %s/state\nsnapshot_interval = 3600\nlink_backoff_max = 1\n%s\n", dir,
            getenv("DAEMON_EXTRA") ? getenv("DAEMON_EXTRA") : "");
    fprintf(f, "[modbus]\ntcp_listen = 127.0.0.1:%u\n", 31000u + (unsigned)getpid() % 900u);
    fprintf(f, "[model:1]\nunit_id = 1\nn = 1\nm = 1\ntype1 = yes\n");
    fprintf(f, "[model:2]\nunit_id = 2\nn = 7\nm = 7\n");
    fprintf(f, "[model:3]\nunit_id = 3\nn = 3\nm = 3\n");
    fprintf(f, "[link:inst]\ntype = serial\ndevice = %s\nbaud = 921600\n%s\n", link_path, extra);
    fclose(f);
    {
        char sd[300];
        snprintf(sd, sizeof sd, "%s/state", dir);
        mkdir(sd, 0700);
    }
    atexit(cleanup);
    daemon_start();
}

/* ---- the peer (instrument + host) with optional faults ----------------- */

typedef struct peer {
    it2n_link l;
    it2n_ostream os;
    unsigned pct;                 /* fault rate per direction */
    uint8_t fr[IT2N_FRAME_MAX_WIRE + 64];
    size_t flen;                  /* frame being written */
    struct { uint32_t at; uint16_t len; uint8_t b[IT2N_FRAME_MAX_WIRE + 64]; } held[16];
    unsigned nheld;               /* delayed frames (reordering), both ways */
    uint8_t in[IT2N_FRAME_MAX_WIRE + 64];
    size_t ilen;
    /* outcomes */
    unsigned acked, nacked, timeouts;
    int last_code;
    it2n_msg_nack last_nack;
    /* host side */
    const it2n_model *ref;
    unsigned results, mismatches, points, events, hellos;
    int32_t want_re;
    uint8_t seen[33 * 33];
    /* spec checks: a trace of what arrived, in order ('A' ACK of ours,
     * 'N' NACK, 'E' EVENT, 'H' HELLO, 'S' SAMPLE_DATA, 'T' STATUS,
     * 'Q' QUERY_RESULT), the daemon's HELLO, the last EVENT, deferred
     * answers (to count the daemon's frames in flight) */
    char trace[4096];
    unsigned ntrace;
    it2n_msg_hello dh;
    it2n_msg_event ev;
    it2n_msg_status status;
    unsigned max_count;
    int defer;
    unsigned defer_ms; /* how long deferred answers wait (0: 20 ms) */
    uint16_t dseq[2 * W];         /* room beyond the window: an overrun shows */
    uint32_t dat[2 * W];
    unsigned nd, max_unanswered;
    unsigned max_pending;         /* most of our frames in flight */
    int32_t watch_seq;            /* >= 0: record the NACK code ... */
    int watch_code;               /* ... the daemon sends for it (0: none) */
    it2n_frame_decoder watch_dec;
} peer;

static void trace(peer *p, char c)
{
    if (p->ntrace + 1 < sizeof p->trace)
        p->trace[p->ntrace++] = c;
}

static peer P;
/* the last frames the peer wrote (reboot: delivered late after a kill) */
static struct { uint16_t len; uint8_t b[IT2N_FRAME_MAX_WIRE + 64]; } last_out[4];
static unsigned nlast_out;

static void raw_write(const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t w = write(master, p, n);
        if (w < 0 && (errno == EAGAIN || errno == EINTR)) {
            usleep(200);
            continue;
        }
        if (w <= 0)
            return;
        p += w;
        n -= (size_t)w;
    }
}

/* A whole frame in one direction: dropped, corrupted, duplicated or held
 * back (reordered) with probability pct each; out = 1 toward the daemon. */
static void fault_frame(peer *p, const uint8_t *b, size_t n, int out)
{
    uint8_t tmp[IT2N_FRAME_MAX_WIRE + 64];
    if (n > sizeof tmp)
        return;
    memcpy(tmp, b, n);
    if (p->pct && rnd() % 100 < p->pct)
        return; /* dropped */
    if (p->pct && rnd() % 100 < p->pct && n > 2)
        tmp[rnd() % (n - 1)] ^= (uint8_t)(1u << (rnd() % 8)); /* corrupted */
    if (p->pct && rnd() % 100 < p->pct && p->nheld < 16) {
        /* held back a few ms: frames sent meanwhile overtake it */
        p->held[p->nheld].at = now_ms() + 2 + rnd() % 10;
        p->held[p->nheld].len = (uint16_t)(n | (out ? 0x8000u : 0u));
        memcpy(p->held[p->nheld].b, tmp, n);
        p->nheld++;
        return;
    }
    if (!out && p->watch_seq >= 0) {
        /* a NACK for a frame our link does not know it sent (written
         * raw): the link drops it as stale, the test reads it here */
        it2n_frame_hdr fh;
        const uint8_t *pl = NULL;
        size_t used = 0, off = 0;
        while (off < n) {
            it2n_msg m;
            int r = it2n_frame_decode(&p->watch_dec, tmp + off, n - off, &used, &fh, &pl);
            off += used;
            if (r == 1 && fh.type == IT2N_MSG_NACK && fh.version == IT2N_PROTO_VERSION &&
                it2n_msg_unpack(fh.type, pl, fh.len, &m, NULL) == IT2N_OK && m.u.nack.seq == (uint16_t)p->watch_seq)
                p->watch_code = m.u.nack.code;
        }
    }
    if (out)
        raw_write(tmp, n);
    else
        it2n_link_input(&p->l, tmp, n, now_ms());
    if (p->pct && rnd() % 100 < p->pct) { /* duplicated */
        if (out)
            raw_write(tmp, n);
        else
            it2n_link_input(&p->l, tmp, n, now_ms());
    }
}

static void release_held(peer *p, int all)
{
    for (unsigned k = 0; k < p->nheld;) {
        if (all || (int32_t)(now_ms() - p->held[k].at) >= 0) {
            size_t n = p->held[k].len & 0x7FFFu;
            if (p->held[k].len & 0x8000u)
                raw_write(p->held[k].b, n);
            else
                it2n_link_input(&p->l, p->held[k].b, n, now_ms());
            p->held[k] = p->held[--p->nheld];
        } else {
            k++;
        }
    }
}

static int os_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    peer *p = s->state;
    if (p->flen + len > sizeof p->fr)
        p->flen = 0;
    memcpy(p->fr + p->flen, buf, len);
    p->flen += len;
    if (buf[len - 1] == 0) {
        fault_frame(p, p->fr, p->flen, 1);
        last_out[nlast_out % 4].len = (uint16_t)p->flen;
        memcpy(last_out[nlast_out++ % 4].b, p->fr, p->flen);
        p->flen = 0;
    }
    return 0;
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    peer *p = app;
    int ret = 0;
    if (p->defer && p->nd < 2 * W) {
        /* answer later: what the daemon sends meanwhile is in flight */
        p->dseq[p->nd] = seq;
        p->dat[p->nd++] = now_ms() + (p->defer_ms ? p->defer_ms : 20u);
        if (p->nd > p->max_unanswered)
            p->max_unanswered = p->nd;
        ret = IT2N_LINK_DEFER;
    }
    switch (m->type) {
    case IT2N_MSG_STATUS:
        trace(p, 'T');
        p->status = m->u.status;
        break;
    case IT2N_MSG_HELLO:
        trace(p, 'H');
        p->dh = m->u.hello;
        p->hellos++;
        it2n_link_set_peer(&p->l, m->u.hello.window, m->u.hello.max_payload);
        break;
    case IT2N_MSG_EVENT:
        trace(p, 'E');
        p->ev = m->u.event;
        p->events++;
        break;
    case IT2N_MSG_QUERY_RESULT: {
        const it2n_msg_query_result *d = &m->u.query_result;
        it2n_point pt;
        trace(p, 'Q');
        it2n_eval(p->ref, it2n_par_from_wire(d->u), it2n_par_from_wire(d->w), &pt, NULL);
        p->mismatches += memcmp(pt.v, d->v, sizeof pt.v) != 0;
        p->results += d->re == (uint16_t)p->want_re || p->want_re < 0;
        break;
    }
    case IT2N_MSG_SAMPLE_DATA: {
        const it2n_msg_sample_data *d = &m->u.sample_data;
        trace(p, 'S');
        if (d->count > p->max_count)
            p->max_count = d->count;
        for (unsigned k = 0; k < d->count; k++) {
            uint32_t idx = d->start + k, r = idx / d->cols, c = idx % d->cols;
            it2n_point pt;
            it2n_eval(p->ref, (it2n_par)(((uint64_t)r << IT2N_PAR_FRAC) / (d->rows - 1u)),
                      (it2n_par)(((uint64_t)c << IT2N_PAR_FRAC) / (d->cols - 1u)), &pt, NULL);
            p->mismatches += memcmp(pt.v[d->fp], d->v[k], sizeof d->v[k]) != 0;
            if (idx < sizeof p->seen && !p->seen[idx]++)
                p->points++;
        }
        break;
    }
    default:
        break;
    }
    return ret;
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *n)
{
    peer *p = app;
    (void)seq;
    trace(p, code == 0 ? 'A' : 'N');
    if (code == 0) {
        p->acked++;
        return;
    }
    if (code == IT2N_PROTO_ERR_TIMEOUT) {
        p->timeouts++;
        return;
    }
    p->nacked++;
    p->last_code = code;
    if (n)
        p->last_nack = *n;
    fprintf(stderr, "  %s seq %u NACKed %d (%s) i %d j %d fp %d\n", it2n_msg_name(type), seq, code,
            code <= -100 ? it2n_proto_strerror(code) : "core", n ? n->i : -9, n ? n->j : -9, n ? n->fp : -9);
}

static void peer_init_w(peer *p, uint16_t first, uint32_t session, unsigned pct, uint32_t rto, uint8_t window);

static void peer_init(peer *p, uint16_t first, uint32_t session, unsigned pct, uint32_t rto)
{
    peer_init_w(p, first, session, pct, rto, 0);
}

static uint8_t peer_version; /* it2n_link_cfg.version of new peers */

static void peer_init_w(peer *p, uint16_t first, uint32_t session, unsigned pct, uint32_t rto, uint8_t window)
{
    it2n_link_cfg c;
    const it2n_model *ref = p->ref;
    memset(p, 0, sizeof *p);
    p->ref = ref;
    p->pct = pct;
    p->os.write = os_write;
    p->os.state = p;
    p->want_re = -1;
    p->watch_seq = -1;
    it2n_frame_decoder_init(&p->watch_dec);
    memset(&c, 0, sizeof c);
    c.out = &p->os;
    c.on_rx = on_rx;
    c.on_done = on_done;
    c.app = p;
    c.rto_ms = rto;
    c.rto_max_ms = 4 * rto;
    c.max_tries = 0; /* the tests decide when to give up */
    c.first_seq = first;
    c.session = session;
    c.window = window;
    c.version = peer_version;
    it2n_link_init(&p->l, &c);
}

/* Read what the daemon wrote, split into frames for the fault model. */
static void pump(peer *p, int wait_ms)
{
    uint8_t buf[4096];
    struct pollfd pf = {master, POLLIN, 0};
    if (wait_ms > 0)
        (void)poll(&pf, 1, wait_ms);
    for (;;) {
        ssize_t n = read(master, buf, sizeof buf);
        if (n <= 0)
            break;
        for (ssize_t k = 0; k < n; k++) {
            if (p->ilen < sizeof p->in)
                p->in[p->ilen++] = buf[k];
            if (buf[k] == 0) {
                fault_frame(p, p->in, p->ilen, 0);
                p->ilen = 0;
            }
        }
    }
    release_held(p, 0);
    for (unsigned k = 0; k < p->nd;) { /* deferred answers come due */
        if ((int32_t)(now_ms() - p->dat[k]) >= 0) {
            it2n_link_complete(&p->l, p->dseq[k], 0, NULL);
            p->dseq[k] = p->dseq[p->nd - 1];
            p->dat[k] = p->dat[--p->nd];
        } else {
            k++;
        }
    }
    it2n_link_poll(&p->l, now_ms());
}

/* Send m (waiting for window room); the sequence number, or -1. */
static int32_t send_msg(peer *p, const it2n_msg *m, uint32_t limit_ms)
{
    uint32_t t0 = now_ms();
    /* a v1.2 peer's HELLO asking for its session goes before anything */
    int asks = m->type == IT2N_MSG_HELLO && p->l.cfg.version == IT2N_PROTO_VERSION_12 &&
               it2n_link_session(&p->l) == 0;
    while (!asks && !it2n_link_can_send(&p->l)) {
        pump(p, 2);
        if (now_ms() - t0 > limit_ms)
            return -1;
    }
    int32_t s = it2n_link_send(&p->l, m, now_ms());
    if (it2n_link_pending(&p->l) > p->max_pending)
        p->max_pending = it2n_link_pending(&p->l);
    return s;
}

static int drain(peer *p, uint32_t limit_ms)
{
    uint32_t t0 = now_ms();
    while (it2n_link_pending(&p->l) || p->nheld) {
        pump(p, 2);
        if (now_ms() - t0 > limit_ms)
            return -1;
    }
    return 0;
}

static it2n_msg hello(void)
{
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_HELLO;
    /* the one version the peer's link speaks */
    m.u.hello.version_min = m.u.hello.version_max = peer_version ? peer_version : IT2N_PROTO_VERSION;
    m.u.hello.max_degree = IT2N_MAX_DEGREE;
    m.u.hello.window = W; /* peer_init_w with a smaller window: overwrite */
    m.u.hello.caps = IT2N_CAP_INSTRUMENT;
    m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
    m.u.hello.max_models = 1;
    memcpy(m.u.hello.node, "daemon_link", 11);
    return m;
}

static it2n_msg model_msg(uint8_t type, uint8_t model)
{
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = type;
    m.u.model.model = model;
    return m;
}

/* Upload ds as model `model` (CONFIGURE, PUTs of `batch`, COMMIT). */
static void upload(peer *p, uint8_t model, const it2n_dataset *ds, unsigned batch, uint32_t limit)
{
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.model = model;
    m.u.configure.n = ds->n;
    m.u.configure.m = ds->m;
    m.u.configure.flags = ds->flags;
    send_msg(p, &m, limit);
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_PUT;
    m.u.put.model = model;
    for (unsigned i = 0; i <= ds->n; i++)
        for (unsigned j = 0; j <= ds->m; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!(ds->present[i][j] & (1u << fp)))
                    continue;
                it2n_put_entry *e = &m.u.put.e[m.u.put.count++];
                e->i = (uint8_t)i;
                e->j = (uint8_t)j;
                e->fp = (uint8_t)fp;
                it2n_dataset_get(ds, i, j, fp, e->vals);
                if (m.u.put.count == batch) {
                    send_msg(p, &m, limit);
                    m.u.put.count = 0;
                }
            }
    if (m.u.put.count)
        send_msg(p, &m, limit);
    m = model_msg(IT2N_MSG_COMMIT, model);
    send_msg(p, &m, limit);
}

/* ---- scenarios ----------------------------------------------------------- */

static void wait_link(void)
{
    /* the daemon opens the link: HELLO until ACKed */
    it2n_msg m = hello();
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    send_msg(&P, &m, 1000);
    CHECK(drain(&P, 10000) == 0, "daemon did not answer HELLO (log %s)", log_path);
}

static void sessions(unsigned n)
{
    static it2n_model ref;
    unsigned lost = 0, refused = 0, ok = 0;
    uint16_t last = P.l.tx_next;
    uint32_t t0 = now_ms();
    for (unsigned s = 0; s < n; s++) {
        it2n_dataset ds;
        it2n_errinfo e;
        it2n_dataset_init(&ds, 1, 1, IT2N_F_TYPE1, NULL);
        for (unsigned i = 0; i <= 1; i++)
            for (unsigned j = 0; j <= 1; j++) {
                it2n_val v[IT2N_CH_COUNT] = {(it2n_val)(10 * i + s % 7) << 24, (it2n_val)(10 * j) << 24, 0,
                                             (it2n_val)((s * 7919u + i * 3 + j) % 1000u) << 14,
                                             (it2n_val)((s * 104729u + j) % 1000u) << 14, 1 << 22};
                it2n_dataset_put(&ds, i, j, IT2N_FP_D, v, false, &e);
            }
        it2n_model_init(&ref);
        if (it2n_model_solve(&ref, &ds, &e) != IT2N_OK) {
            fprintf(stderr, "local solve %u failed\n", s);
            lost++;
            continue;
        }
        /* first number inside the daemon's history of the last session */
        peer_init(&P, (uint16_t)(last - 1u - rnd() % W), rnd(), 0, 100);
        P.ref = &ref;
        it2n_msg h = hello();
        send_msg(&P, &h, 2000);
        upload(&P, 1, &ds, 2, 2000);
        /* readers see the last durable state: query after COMMIT's ACK */
        drain(&P, 5000);
        it2n_msg q;
        memset(&q, 0, sizeof q);
        q.type = IT2N_MSG_QUERY;
        q.u.query.model = 1;
        send_msg(&P, &q, 2000);
        q.u.query.u = q.u.query.w = IT2N_WIRE_PAR_ONE;
        send_msg(&P, &q, 2000);
        if (drain(&P, 5000) != 0) {
            lost++;
            continue;
        }
        /* wait for both results (responses follow the ACKs) */
        for (uint32_t t1 = now_ms(); P.results < 2 && now_ms() - t1 < 2000;)
            pump(&P, 2);
        refused += P.nacked;
        if (P.results != 2 || P.mismatches || P.nacked || P.acked != 7)
            lost++;
        else
            ok++;
        last = P.l.tx_next;
    }
    printf("sessions: %u back-to-back on one link, first seq inside the daemon's history: %u ok, %u lost, "
           "%u refused, %u ms\n", n, ok, lost, refused, now_ms() - t0);
    CHECK(lost == 0 && refused == 0 && ok == n, "sessions: %u lost, %u refused", lost, refused);
}

static void kills(unsigned k)
{
    static it2n_dataset ds;
    static it2n_model ref;
    it2n_errinfo e;
    unsigned killed = 0, sent = 0;
    CHECK(synth_dataset(&ds, 7, 7, 0, 77, &e) == IT2N_OK, "synth");
    it2n_model_init(&ref);
    CHECK(it2n_model_solve(&ref, &ds, &e) == IT2N_OK, "local solve");
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 50);
    P.ref = &ref;
    it2n_msg h = hello();
    send_msg(&P, &h, 2000);
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.model = 2;
    m.u.configure.n = 7;
    m.u.configure.m = 7;
    send_msg(&P, &m, 2000);
    drain(&P, 5000);
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_PUT;
    m.u.put.model = 2;
    unsigned total = 0;
    for (unsigned i = 0; i <= 7; i++)
        for (unsigned j = 0; j <= 7; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_put_entry *en = &m.u.put.e[m.u.put.count++];
                en->i = (uint8_t)i;
                en->j = (uint8_t)j;
                en->fp = (uint8_t)fp;
                it2n_dataset_get(&ds, i, j, fp, en->vals);
                total++;
                if (m.u.put.count < 7 && total < 448)
                    continue;
                CHECK(send_msg(&P, &m, 20000) >= 0, "PUT send");
                sent++;
                m.u.put.count = 0;
                /* every few PUTs: kill -9 with frames in flight, restart */
                if (killed < k && killed * 60u < k * sent && it2n_link_pending(&P.l) > 0) {
                    if (killed == 0 && k >= 5) {
                        /* Once for sure: the PUTs in flight stored and
                         * ACKed, the ACKs lost on the line (read and
                         * dropped), then the kill: delivery unknown, the
                         * re-sent PUTs must hit the rule. */
                        uint8_t junk[512];
                        usleep(300000);
                        while (read(master, junk, sizeof junk) > 0)
                            ;
                    } else {
                        pump(&P, rnd() % 3); /* some delivered, some ACKs unread */
                    }
                    daemon_kill(SIGKILL);
                    killed++;
                    daemon_start();
                }
            }
    drain(&P, 30000);
    unsigned put_acked = P.acked;
    m = model_msg(IT2N_MSG_COMMIT, 2);
    send_msg(&P, &m, 5000);
    drain(&P, 10000);
    it2n_msg q;
    memset(&q, 0, sizeof q);
    q.type = IT2N_MSG_QUERY;
    q.u.query.model = 2;
    q.u.query.u = IT2N_WIRE_PAR_ONE / 3;
    q.u.query.w = IT2N_WIRE_PAR_ONE / 7;
    send_msg(&P, &q, 5000);
    for (uint32_t t1 = now_ms(); P.results < 1 && now_ms() - t1 < 5000;)
        pump(&P, 2);
    printf("kill -9: %u kills mid-upload, %u PUTs sent, %u ACKed, %u NACKed, %u retransmissions, "
           "solved model %s the local solve\n",
           killed, sent, put_acked - 2, P.nacked, P.l.stats.tx_retx,
           P.results == 1 && !P.mismatches ? "equals" : "DIFFERS FROM");
    {
        /* how many re-sent PUTs found their entries stored (the rule) */
        char cmd[400];
        snprintf(cmd, sizeof cmd, "grep -c 'already stored with these values' '%s'", log_path);
        FILE *g = popen(cmd, "r");
        unsigned idem = 0;
        if (g) {
            if (fscanf(g, "%u", &idem) != 1)
                idem = 0;
            pclose(g);
        }
        printf("kill -9: %u re-sent PUTs were found already stored (idempotent success)\n", idem);
        if (k >= 5)
            CHECK(idem > 0, "no re-sent PUT hit a stored entry: the case under test did not happen");
    }
    CHECK(killed == k, "killed %u of %u", killed, k);
    CHECK(P.nacked == 0, "%u NACKs (last %d)", P.nacked, P.last_code);
    /* v1.2: each HELLO re-sent for a new session (after a restart) is
     * answered too */
    unsigned rehellos = peer_version ? P.l.stats.tx_hellos - 1u : 0u;
    if (peer_version)
        printf("kill -9 (v1.2 peer): %u HELLOs re-sent by the link for a new session\n", rehellos);
    CHECK(put_acked == 2 + sent + rehellos, "ACKs %u for %u PUTs", put_acked - 2 - rehellos, sent);
    CHECK(P.results == 1 && P.mismatches == 0, "query after the kills");
}

static void lossy(unsigned pct)
{
    static it2n_dataset ds;
    static it2n_model ref;
    it2n_errinfo e;
    CHECK(synth_dataset(&ds, 3, 3, 0, 5, &e) == IT2N_OK, "synth");
    it2n_model_init(&ref);
    CHECK(it2n_model_solve(&ref, &ds, &e) == IT2N_OK, "local solve");
    peer_init(&P, (uint16_t)rnd(), rnd(), pct, 40);
    P.ref = &ref;
    uint32_t t0 = now_ms();
    it2n_msg h = hello();
    send_msg(&P, &h, 5000);
    upload(&P, 3, &ds, 19, 20000);
    CHECK(drain(&P, 30000) == 0, "upload not acknowledged");
    uint32_t t_up = now_ms();
    for (unsigned k = 0; k < 16; k++) {
        it2n_msg q;
        memset(&q, 0, sizeof q);
        q.type = IT2N_MSG_QUERY;
        q.u.query.model = 3;
        q.u.query.u = (uint32_t)(k * (IT2N_WIRE_PAR_ONE / 15u));
        q.u.query.w = IT2N_WIRE_PAR_ONE - q.u.query.u;
        CHECK(send_msg(&P, &q, 20000) >= 0, "QUERY %u", k);
    }
    it2n_msg s;
    memset(&s, 0, sizeof s);
    s.type = IT2N_MSG_SAMPLE;
    s.u.sample.model = 3;
    s.u.sample.fp = IT2N_FP_D;
    s.u.sample.rows = 33;
    s.u.sample.cols = 33;
    CHECK(send_msg(&P, &s, 20000) >= 0, "SAMPLE");
    uint32_t t1 = now_ms();
    while ((P.results < 16 || P.points < 33 * 33) && now_ms() - t1 < 60000)
        pump(&P, 2);
    if (getenv("DL_DEBUG"))
        fprintf(stderr, "  upload %u ms, requests sent %u ms, responses %u ms; host: gaps %u fast %u\n",
                t_up - t0, t1 - t_up, now_ms() - t1, P.l.stats.tx_gaps, P.l.stats.tx_fast_retx);
    drain(&P, 10000);
    release_held(&P, 1);
    printf("lossy %u%%: session (HELLO, 1 CONFIGURE + 9 PUT + COMMIT, 16 QUERY, SAMPLE 33x33) in %u ms, "
           "%u/16 results, %u/1089 points, %u mismatches, 0 re-requests; host retx %u, buffered %u, "
           "dup %u; NACKs %u\n",
           pct, now_ms() - t0, P.results, P.points, P.mismatches, P.l.stats.tx_retx, P.l.stats.rx_buffered,
           P.l.stats.rx_dup, P.nacked);
    CHECK(P.results == 16 && P.points == 33 * 33 && P.mismatches == 0, "lossy: responses incomplete");
    CHECK(P.nacked == 0, "lossy: %u NACKs", P.nacked);
    if (pct)
        CHECK(P.l.stats.tx_retx > 0 && P.l.stats.rx_dup + P.l.stats.rx_buffered > 0, "faults not exercised");
}

static void settle(peer *p, unsigned ms);

/* The window negotiated per peer (see the header comment, "wide"). */
static void wide(unsigned rounds)
{
    static it2n_dataset ds;
    static it2n_model ref;
    it2n_errinfo e;
    CHECK(synth_dataset(&ds, 7, 7, IT2N_F_Z, 11, &e) == IT2N_OK, "synth");
    it2n_model_init(&ref);
    CHECK(it2n_model_solve(&ref, &ds, &e) == IT2N_OK, "local solve");
    for (unsigned pass = 0; pass < 2; pass++) {
        uint8_t win = pass == 0 ? (uint8_t)W : 4u;
        unsigned puts = 0;
        peer_init_w(&P, (uint16_t)rnd(), rnd(), 0, 100, win);
        P.ref = &ref;
        it2n_msg h = hello();
        h.u.hello.window = it2n_link_window(&P.l);
        send_msg(&P, &h, 5000);
        for (uint32_t t0 = now_ms(); !P.hellos && now_ms() - t0 < 5000;)
            pump(&P, 2);
        CHECK(P.hellos == 1 && P.dh.window == IT2N_PROTO_WINDOW, "daemon HELLO window %u, want its build's %u",
              P.dh.window, (unsigned)IT2N_PROTO_WINDOW);
        CHECK(it2n_link_send_window(&P.l) == win, "negotiated %u, want %u", it2n_link_send_window(&P.l), win);
        uint32_t t0 = now_ms();
        for (unsigned r = 0; r < rounds; r++)
            upload(&P, 2, &ds, 19, 20000);
        CHECK(drain(&P, 30000) == 0, "upload not acknowledged");
        uint32_t t_up = now_ms() - t0;
        puts = (unsigned)((448u + 18u) / 19u);
        CHECK(P.acked == 1 + rounds * (puts + 2u) && P.nacked == 0 && P.timeouts == 0,
              "window %u: %u ACKed of %u, %u NACKed, %u timed out", win, P.acked, 1 + rounds * (puts + 2u),
              P.nacked, P.timeouts);
        CHECK(P.max_pending == win, "window %u: at most %u of our frames in flight", win, P.max_pending);
        /* the daemon's frames: a 33x33 SAMPLE run, answers deferred 250 ms:
         * the daemon's line clock writes its frames at the line's pace
         * (921 600 Bd: 11 ms each), so it fills its window of 16 before the
         * first answer, and its RTO (300 ms) does not run out first */
        P.defer = 1;
        P.defer_ms = 250;
        it2n_msg sm;
        memset(&sm, 0, sizeof sm);
        sm.type = IT2N_MSG_SAMPLE;
        sm.u.sample.model = 2;
        sm.u.sample.fp = IT2N_FP_D;
        sm.u.sample.rows = sm.u.sample.cols = 33;
        CHECK(send_msg(&P, &sm, 5000) >= 0, "SAMPLE");
        for (uint32_t t1 = now_ms(); P.points < 33 * 33 && now_ms() - t1 < 30000;)
            pump(&P, 2);
        drain(&P, 5000);
        settle(&P, 400); /* the last deferred answers come due */
        P.defer = 0;
        P.defer_ms = 0;
        printf("wide: window %u peer: %u x (CONFIGURE, %u PUT, COMMIT) in %u ms, at most %u PUTs in flight, "
               "0 lost; SAMPLE 33x33: %u points, at most %u daemon frames in flight, %u mismatches\n",
               win, rounds, puts, t_up, P.max_pending, P.points, P.max_unanswered, P.mismatches);
        CHECK(P.points == 33 * 33 && P.mismatches == 0, "SAMPLE: %u points, %u mismatches", P.points, P.mismatches);
        CHECK(P.max_unanswered == win, "window %u: the daemon kept %u frames in flight", win, P.max_unanswered);
    }
}

/* Send m and wait for its answer; returns the code (0 ACK). */
static int request(peer *p, const it2n_msg *m)
{
    unsigned before = p->acked + p->nacked;
    if (send_msg(p, m, 5000) < 0)
        return 1;
    for (uint32_t t0 = now_ms(); p->acked + p->nacked == before && now_ms() - t0 < 5000;)
        pump(p, 2);
    if (p->acked + p->nacked == before)
        return 2;
    return p->nacked && p->acked + p->nacked > before && p->trace[p->ntrace - 1] == 'N' ? p->last_code : 0;
}

static void settle(peer *p, unsigned ms)
{
    for (uint32_t t0 = now_ms(); now_ms() - t0 < ms;)
        pump(p, 2);
}

static it2n_msg put1(uint8_t model, uint8_t i, uint8_t j, uint8_t fp, it2n_val z)
{
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_PUT;
    m.u.put.model = model;
    m.u.put.count = 1;
    m.u.put.e[0].i = i;
    m.u.put.e[0].j = j;
    m.u.put.e[0].fp = fp;
    m.u.put.e[0].vals[IT2N_CH_X] = (it2n_val)i << 24;
    m.u.put.e[0].vals[IT2N_CH_Y] = (it2n_val)j << 24;
    m.u.put.e[0].vals[IT2N_CH_Z] = z;
    m.u.put.e[0].vals[IT2N_CH_T] = 1 << 23;
    return m;
}

/* Issue 11 item 5 (and 4): the gaps the issue lists, each driven on the
 * wire against the daemon. Needs the daemon's default RTO (no rto_ms) and
 * peer_timeout_ms = 600 in the link section. */
static void spec(unsigned unused)
{
    static it2n_dataset ds;
    static it2n_model ref;
    it2n_errinfo e;
    int r;
    (void)unused;
    CHECK(synth_dataset(&ds, 3, 3, 0, 9, &e) == IT2N_OK, "synth");
    it2n_model_init(&ref);
    CHECK(it2n_model_solve(&ref, &ds, &e) == IT2N_OK, "local solve");

    /* No common version: NACK VERSION, value = our highest, lo..hi = the
     * daemon's versions. */
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    it2n_msg h = hello();
    h.u.hello.version_min = h.u.hello.version_max = 1;
    r = request(&P, &h);
    CHECK(r == IT2N_PROTO_ERR_VERSION && P.last_nack.value == 1 && P.last_nack.lo == IT2N_PROTO_VERSION_MIN &&
              P.last_nack.hi == IT2N_PROTO_VERSION_MAX,
          "HELLO without a common version: %d value %lld lo %lld hi %lld", r, (long long)P.last_nack.value,
          (long long)P.last_nack.lo, (long long)P.last_nack.hi);
    CHECK(P.hellos == 0, "a refused HELLO got the daemon's HELLO");

    /* HELLO is optional: a session without it is served (no EVENTs). */
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    P.ref = &ref;
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.model = 1;
    m.u.configure.n = m.u.configure.m = 1;
    m.u.configure.flags = IT2N_F_TYPE1;
    CHECK(request(&P, &m) == 0, "CONFIGURE without HELLO");
    settle(&P, 100);
    CHECK(P.events == 0, "EVENT to a peer that said no HELLO");

    /* HELLO answered by ACK, then the daemon's HELLO (type 0x01, not
     * 0x41), whose max_models is the number of model ids it serves. */
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    P.ref = &ref;
    h = hello();
    h.u.hello.caps |= IT2N_CAP_EVENTS;
    CHECK(request(&P, &h) == 0, "HELLO");
    settle(&P, 100);
    CHECK(P.hellos == 1 && P.trace[0] == 'A' && P.trace[1] == 'H', "HELLO answer: trace %.*s", (int)P.ntrace,
          P.trace);
    CHECK(P.dh.max_models == 3 && P.dh.version_min == IT2N_PROTO_VERSION_MIN &&
              P.dh.version_max == IT2N_PROTO_VERSION_MAX && (P.dh.caps & IT2N_CAP_SERVER),
          "daemon HELLO: max_models %u versions %u..%u", P.dh.max_models, P.dh.version_min, P.dh.version_max);

    /* CONFIGURE: its ACK comes before the CONFIGURED EVENT. */
    P.ntrace = 0;
    m.u.configure.model = 1;
    CHECK(request(&P, &m) == 0, "CONFIGURE");
    settle(&P, 100);
    CHECK(P.ntrace >= 2 && P.trace[0] == 'A' && P.trace[1] == 'E' && P.ev.kind == IT2N_EV_CONFIGURED,
          "CONFIGURE ACK then EVENT CONFIGURED: trace %.*s kind %u", (int)P.ntrace, P.trace, P.ev.kind);

    /* NACK details. Unknown model: MODEL, value = the id. */
    m.u.configure.model = 9;
    r = request(&P, &m);
    CHECK(r == IT2N_PROTO_ERR_MODEL && P.last_nack.value == 9, "unknown model: %d value %lld", r,
          (long long)P.last_nack.value);
    /* type-1 model, footprint LL: INVAL, value 0, lo..hi = 3..3 (D only) */
    it2n_msg pm = put1(1, 0, 0, IT2N_FP_LL, 0);
    r = request(&P, &pm);
    CHECK(r == IT2N_ERR_INVAL && P.last_nack.value == 0 && P.last_nack.lo == IT2N_FP_D &&
              P.last_nack.hi == IT2N_FP_D && P.last_nack.fp == IT2N_FP_LL,
          "type-1 fp LL: %d value %lld lo %lld hi %lld", r, (long long)P.last_nack.value,
          (long long)P.last_nack.lo, (long long)P.last_nack.hi);
    /* i > n: INVAL with the entry's fp (not -1), value i, hi n */
    pm = put1(1, 5, 0, IT2N_FP_D, 0);
    r = request(&P, &pm);
    CHECK(r == IT2N_ERR_INVAL && P.last_nack.i == 5 && P.last_nack.fp == IT2N_FP_D && P.last_nack.value == 5 &&
              P.last_nack.hi == 1,
          "i > n: %d i %d fp %d value %lld hi %lld", r, P.last_nack.i, P.last_nack.fp,
          (long long)P.last_nack.value, (long long)P.last_nack.hi);
    /* z for a model without z: RANGE on channel z, never dropped */
    pm = put1(1, 0, 0, IT2N_FP_D, 5 << 24);
    r = request(&P, &pm);
    CHECK(r == IT2N_ERR_RANGE && P.last_nack.ch == IT2N_CH_Z && P.last_nack.value == 5 << 24,
          "z on a model without z: %d ch %d", r, P.last_nack.ch);
    /* COMMIT of an incomplete model: MISSING with ch -1 */
    pm = put1(1, 0, 0, IT2N_FP_D, 0);
    CHECK(request(&P, &pm) == 0, "PUT (0,0)");
    /* the same entry again, no REPLACE: idempotent success */
    CHECK(request(&P, &pm) == 0, "identical PUT again");
    /* ... also from a restarted instrument (a new session re-sending a PUT
     * whose delivery it does not know), with no generation change */
    {
        it2n_msg gs1 = model_msg(IT2N_MSG_GET_STATUS, 1);
        CHECK(request(&P, &gs1) == 0, "GET_STATUS");
        settle(&P, 50);
        uint32_t gen0 = P.status.generation;
        peer_init(&P, (uint16_t)(P.l.tx_next - 1u), rnd(), 0, 100);
        P.ref = &ref;
        CHECK(request(&P, &pm) == 0, "identical PUT from a new session");
        CHECK(request(&P, &gs1) == 0, "GET_STATUS");
        settle(&P, 50);
        CHECK(P.status.generation == gen0, "re-sent PUT changed the generation %u -> %u", gen0,
              P.status.generation);
    }
    pm.u.put.e[0].vals[IT2N_CH_T] = 1 << 22;
    r = request(&P, &pm);
    CHECK(r == IT2N_ERR_DUPLICATE, "different value at a stored entry: %d (want DUPLICATE)", r);
    it2n_msg cm = model_msg(IT2N_MSG_COMMIT, 1);
    r = request(&P, &cm);
    CHECK(r == IT2N_ERR_MISSING && P.last_nack.ch == -1 && P.last_nack.fp >= 0, "MISSING: %d ch %d fp %d", r,
          P.last_nack.ch, P.last_nack.fp);

    /* RESET: points gone, configuration (degrees, flags) kept, EMPTY */
    it2n_msg rs = model_msg(IT2N_MSG_RESET, 1);
    CHECK(request(&P, &rs) == 0, "RESET");
    it2n_msg gs = model_msg(IT2N_MSG_GET_STATUS, 1);
    CHECK(request(&P, &gs) == 0, "GET_STATUS");
    settle(&P, 100);
    CHECK(P.status.state == IT2N_MS_EMPTY && P.status.n == 1 && P.status.m == 1 &&
              P.status.flags == IT2N_F_TYPE1 && P.status.missing == 4,
          "after RESET: state %u n %u m %u flags %u missing %u", P.status.state, P.status.n, P.status.m,
          P.status.flags, P.status.missing);

    /* SAMPLE above 65 536 nodes: RANGE, value = nodes asked, hi = limit;
     * checked before the model (protocol.md 5.8): an unknown model still
     * gets RANGE (issue 17 point 18) */
    {
        it2n_msg big;
        memset(&big, 0, sizeof big);
        big.type = IT2N_MSG_SAMPLE;
        big.u.sample.model = 200;
        big.u.sample.fp = IT2N_FP_D;
        big.u.sample.rows = 257;
        big.u.sample.cols = 256;
        r = request(&P, &big);
        CHECK(r == IT2N_ERR_RANGE && P.last_nack.value == 257 * 256,
              "SAMPLE 257x256 of an unknown model: %d (want RANGE before MODEL)", r);
    }
    unsigned nk0 = P.nacked;
    upload(&P, 3, &ds, 19, 5000);
    CHECK(drain(&P, 10000) == 0 && P.nacked == nk0, "upload model 3 (%u NACKs)", P.nacked - nk0);
    it2n_msg sm;
    memset(&sm, 0, sizeof sm);
    sm.type = IT2N_MSG_SAMPLE;
    sm.u.sample.model = 3;
    sm.u.sample.fp = IT2N_FP_D;
    sm.u.sample.rows = 257;
    sm.u.sample.cols = 256;
    r = request(&P, &sm);
    CHECK(r == IT2N_ERR_RANGE && P.last_nack.value == 257 * 256 && P.last_nack.hi == 65536,
          "SAMPLE 257x256: %d value %lld hi %lld", r, (long long)P.last_nack.value, (long long)P.last_nack.hi);

    /* Requests during a response run wait for it: never BUSY; the STATUS
     * comes after the last SAMPLE_DATA. */
    settle(&P, 50);
    P.ntrace = 0;
    unsigned nacked = P.nacked;
    sm.u.sample.rows = sm.u.sample.cols = 33;
    CHECK(send_msg(&P, &sm, 2000) >= 0, "SAMPLE");
    CHECK(send_msg(&P, &gs, 2000) >= 0, "GET_STATUS");
    it2n_msg q;
    memset(&q, 0, sizeof q);
    q.type = IT2N_MSG_QUERY;
    q.u.query.model = 3;
    CHECK(send_msg(&P, &q, 2000) >= 0, "QUERY");
    drain(&P, 10000);
    settle(&P, 300);
    {
        const char *t = memchr(P.trace, 'T', P.ntrace), *lastS = NULL;
        for (unsigned k = 0; k < P.ntrace; k++)
            if (P.trace[k] == 'S')
                lastS = P.trace + k;
        CHECK(P.nacked == nacked && t && lastS && t > lastS && memchr(P.trace, 'Q', P.ntrace),
              "requests during a SAMPLE run: %u NACKs, trace %.*s", P.nacked - nacked, (int)P.ntrace, P.trace);
    }

    /* A peer over its window (issue 17, docs/protocol.md 4.3 rule 3, 5.1):
     * 16 requests wait behind a SAMPLE run (the daemon's window), a 17th
     * sent while the first still waits is refused NACK BUSY and has no
     * effect; the 16 are served in order after the run. */
    peer_init_w(&P, (uint16_t)rnd(), rnd(), 0, 100, 16);
    P.ref = &ref;
    h = hello();
    CHECK(request(&P, &h) == 0, "HELLO window 16");
    for (uint32_t t0 = now_ms(); P.hellos == 0 && now_ms() - t0 < 2000;)
        pump(&P, 2); /* the daemon's HELLO: its window */
    CHECK(it2n_link_send_window(&P.l) == 16, "send window after the daemon's HELLO: %u",
          (unsigned)it2n_link_send_window(&P.l));
    settle(&P, 50);
    P.ntrace = 0;
    P.defer = 1;        /* the run waits for our answers ... */
    P.defer_ms = 250;   /* ... long enough to queue the requests */
    sm.u.sample.rows = sm.u.sample.cols = 33;
    CHECK(send_msg(&P, &sm, 2000) >= 0, "SAMPLE (over-window test)");
    for (unsigned k = 0; k < 16; k++)
        CHECK(send_msg(&P, &gs, 2000) >= 0, "GET_STATUS %u of 16", k);
    for (uint32_t t0 = now_ms(); P.acked < 2 && now_ms() - t0 < 300;)
        pump(&P, 2); /* the HELLO and the SAMPLE are answered; 16 wait */
    CHECK(!it2n_link_can_send(&P.l), "a 17th request fits the window");
    {
        /* break 4.2 rule 2 on purpose: the next number, written raw (the
         * link has no 17th slot), and taken from the link's sequence */
        it2n_frame_hdr fh;
        uint8_t pl[8];
        int n = it2n_msg_pack(&gs, pl, sizeof pl, NULL);
        fh.version = IT2N_PROTO_VERSION;
        fh.type = gs.type;
        fh.flags = IT2N_FLAG_REL;
        fh.seq = P.l.tx_next++;
        fh.len = (uint16_t)n;
        P.watch_seq = fh.seq;
        P.watch_code = 0;
        CHECK(n > 0 && it2n_frame_write(&P.os, &fh, pl, (size_t)n) > 0, "GET_STATUS 17 (over the window)");
        for (uint32_t t0 = now_ms(); P.watch_code == 0 && now_ms() - t0 < 300;)
            pump(&P, 2);
        CHECK(P.watch_code == IT2N_PROTO_ERR_BUSY, "over the window: answer %d (want NACK BUSY)", P.watch_code);
        P.watch_seq = -1;
    }
    P.defer = 0;
    drain(&P, 10000);
    settle(&P, 300);
    {
        unsigned ts = 0;
        for (unsigned k = 0; k < P.ntrace; k++)
            ts += P.trace[k] == 'T';
        printf("spec: a peer over its window: NACK BUSY, %u STATUS for the 16 requests within it\n", ts);
        CHECK(ts == 16, "STATUS responses: %u (want 16: the refused request had no effect)", ts);
    }

    /* Negotiated limits: window 1, max_payload 64 — SAMPLE_DATA of one
     * point and one frame in flight; QUERY_RESULT (447) refused NOSPACE. */
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    P.ref = &ref;
    h = hello();
    h.u.hello.window = 1;
    h.u.hello.max_payload = 64;
    CHECK(request(&P, &h) == 0, "HELLO window 1");
    r = request(&P, &q);
    CHECK(r == IT2N_PROTO_ERR_NOSPACE && P.last_nack.value == 447 && P.last_nack.hi == 64,
          "QUERY to a 64-byte peer: %d value %lld hi %lld", r, (long long)P.last_nack.value,
          (long long)P.last_nack.hi);
    settle(&P, 100);
    memset(P.seen, 0, sizeof P.seen);
    P.points = 0;
    P.defer = 1;
    sm.u.sample.rows = sm.u.sample.cols = 8;
    CHECK(send_msg(&P, &sm, 2000) >= 0, "SAMPLE 8x8");
    for (uint32_t t0 = now_ms(); P.points < 64 && now_ms() - t0 < 20000;)
        pump(&P, 2);
    P.defer = 0;
    settle(&P, 100);
    printf("spec: window 1 / max_payload 64 peer: %u points, at most %u per SAMPLE_DATA, at most %u "
           "unanswered daemon frames\n", P.points, P.max_count, P.max_unanswered);
    CHECK(P.points == 64 && P.max_count == 1 && P.max_unanswered == 1, "limits: %u points, count %u, in flight %u",
          P.points, P.max_count, P.max_unanswered);
    /* the same with window 4: more in flight (the check can fail) */
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    P.ref = &ref;
    h = hello();
    CHECK(request(&P, &h) == 0, "HELLO window 4");
    settle(&P, 50);
    P.defer = 1;
    CHECK(send_msg(&P, &sm, 2000) >= 0, "SAMPLE 8x8");
    for (uint32_t t0 = now_ms(); P.points < 64 && now_ms() - t0 < 20000;)
        pump(&P, 2);
    P.defer = 0;
    settle(&P, 100);
    CHECK(P.max_count == 21 && P.max_unanswered > 1, "window 4: count %u, in flight %u", P.max_count,
          P.max_unanswered);

    /* RTO from the baud rate (921 600: 20 + 1046 x 10 / 921.6 = 32 ms,
     * counted from when the frame has left the line; protocol.md 4.2 rule
     * 3): the daemon's first retransmission of an unanswered frame comes
     * no sooner (nor much later: the STATUS frame takes 0.3 ms on the
     * line, and this peer sends nothing meanwhile); then, silent past
     * peer_timeout_ms, the link is declared
     * down and the next word from the peer brings EVENT LOST. */
    settle(&P, 100);
    P.defer = 1;
    P.nd = 0;
    unsigned rx_before = P.l.stats.rx_dup;
    uint32_t t0 = now_ms();
    CHECK(send_msg(&P, &gs, 2000) >= 0, "GET_STATUS");
    /* hold every answer: the STATUS frame stays unanswered */
    uint32_t first_retx = 0;
    while (now_ms() - t0 < 1500) {
        for (unsigned k = 0; k < P.nd; k++)
            P.dat[k] = now_ms() + 100000;
        pump(&P, 2);
        if (!first_retx && P.l.stats.rx_dup > rx_before)
            first_retx = now_ms() - t0;
    }
    P.nd = 0;
    P.defer = 0;
    printf("spec: daemon's first retransmission after %u ms (default RTO at 921600 baud: %u ms)\n", first_retx,
           it2n_link_rto_default(921600));
    /* ... nor much later: the daemon re-arms its timer for a frame's own
     * deadline (it used to wait for its 100 ms poll tick: 78-83 ms) */
    CHECK(first_retx >= it2n_link_rto_default(921600) && first_retx < 2 * it2n_link_rto_default(921600) + 10,
          "first retransmission after %u ms", first_retx);
    P.events = 0;
    P.ev.kind = 0;
    CHECK(request(&P, &gs) == 0, "GET_STATUS after the link was declared down");
    settle(&P, 300);
    CHECK(P.ev.kind == IT2N_EV_LOST && P.ev.model == 0xFF && P.ev.code == IT2N_PROTO_ERR_DOWN &&
              P.ev.generation >= 1,
          "EVENT LOST: kind %u model %u code %d frames %u", P.ev.kind, P.ev.model, P.ev.code,
          (unsigned)P.ev.generation);

    /* EVENT LOST goes only to the session whose frames were dropped (and
     * that said HELLO): declared down again, then a new session speaks
     * (the peer restarted, its HELLO-less first frame): no LOST for it. */
    settle(&P, 100);
    P.defer = 1;
    P.nd = 0;
    CHECK(send_msg(&P, &gs, 2000) >= 0, "GET_STATUS");
    for (uint32_t t1 = now_ms(); now_ms() - t1 < 1500;) {
        for (unsigned k = 0; k < P.nd; k++)
            P.dat[k] = now_ms() + 100000;
        pump(&P, 2);
    }
    peer_init(&P, (uint16_t)rnd(), rnd(), 0, 100);
    P.ref = &ref;
    it2n_msg h2 = hello();
    h2.u.hello.caps |= IT2N_CAP_EVENTS; /* it asks for events, and still */
    CHECK(request(&P, &h2) == 0, "HELLO of a new session after the link was declared down");
    CHECK(request(&P, &gs) == 0, "GET_STATUS of a new session after the link was declared down");
    settle(&P, 300);
    CHECK(P.events == 0, "EVENT (kind %u) to a new session for the previous one's frames", P.ev.kind);
    printf("spec: %d checks failed\n", failures);
}

/* ---- the worked example of docs/instrument.md ------------------------ */
#ifdef DOC_EXAMPLE
#include "it2n_inst.h"
int upload_and_query(it2n_val *t_centre, it2n_msg_nack *why);
int board_uart_write(const uint8_t *buf, size_t len);
int board_uart_read(uint8_t *buf, size_t len);
uint32_t board_millis(void);

int board_uart_write(const uint8_t *buf, size_t len)
{
    raw_write(buf, len);
    return 0;
}

int board_uart_read(uint8_t *buf, size_t len)
{
    ssize_t n = read(master, buf, len);
    return n > 0 ? (int)n : 0;
}

uint32_t board_millis(void)
{
    return now_ms();
}


/* ---- v1.2: limits announced again after a daemon restart (5.2) ---------- */

static void relimit(unsigned unused)
{
    static it2n_dataset ds;
    static it2n_model ref;
    it2n_errinfo e;
    (void)unused;
    it2n_dataset_init(&ds, 1, 1, IT2N_F_TYPE1, NULL);
    for (unsigned i = 0; i <= 1; i++)
        for (unsigned j = 0; j <= 1; j++) {
            it2n_val v[IT2N_CH_COUNT] = {(it2n_val)(10 * i) << 24, (it2n_val)(10 * j) << 24, 0,
                                         (it2n_val)(3 + i + j) << 21, 1 << 21, 1 << 20};
            it2n_dataset_put(&ds, i, j, IT2N_FP_D, v, false, &e);
        }
    it2n_model_init(&ref);
    CHECK(it2n_model_solve(&ref, &ds, &e) == IT2N_OK, "local solve");
    peer_version = IT2N_PROTO_VERSION_12;
    peer_init(&P, 0, 0, 0, 100);
    P.ref = &ref;
    it2n_msg h = hello();
    h.u.hello.max_payload = 64; /* one SAMPLE_DATA point per frame */
    CHECK(request(&P, &h) == 0, "v1.2 HELLO");
    uint32_t s1 = it2n_link_session(&P.l);
    upload(&P, 1, &ds, 2, 2000);
    CHECK(drain(&P, 5000) == 0 && P.nacked == 0, "upload");
    it2n_msg sm;
    memset(&sm, 0, sizeof sm);
    sm.type = IT2N_MSG_SAMPLE;
    sm.u.sample.model = 1;
    sm.u.sample.fp = IT2N_FP_D;
    sm.u.sample.rows = sm.u.sample.cols = 3;
    CHECK(request(&P, &sm) == 0, "SAMPLE");
    for (uint32_t t0 = now_ms(); P.points < 9 && now_ms() - t0 < 3000;)
        pump(&P, 2);
    CHECK(P.points == 9 && P.max_count == 1 && !P.mismatches, "before: %u points, at most %u per frame", P.points,
          P.max_count);
    /* kill -9 and restart: the new daemon knows neither the session nor
     * the limits; the peer's next frame is refused (SESSION) and its link
     * sends the HELLO again by itself */
    daemon_kill(SIGKILL);
    daemon_start();
    memset(P.seen, 0, sizeof P.seen);
    P.points = P.max_count = 0;
    it2n_msg gs = model_msg(IT2N_MSG_GET_STATUS, 1);
    int r = 2;
    for (uint32_t t0 = now_ms(); r == 2 && now_ms() - t0 < 10000;)
        r = request(&P, &gs); /* the daemon reopens the line meanwhile */
    CHECK(r == 0, "GET_STATUS after the restart: %d", r);
    CHECK(request(&P, &sm) == 0, "SAMPLE after the restart");
    for (uint32_t t0 = now_ms(); P.points < 9 && now_ms() - t0 < 3000;)
        pump(&P, 2);
    printf("relimit (v1.2): daemon kill -9 and restart: the peer's HELLO re-sent by its link (%u HELLOs asked, "
           "%u answered), session %08x -> %08x, SAMPLE after: %u points, at most %u per frame (max_payload 64)\n",
           (unsigned)P.l.stats.tx_hellos, P.hellos, (unsigned)s1, (unsigned)it2n_link_session(&P.l), P.points,
           P.max_count);
    CHECK(P.l.stats.tx_hellos == 2 && P.hellos == 2 && it2n_link_session(&P.l) != s1 &&
              it2n_link_session(&P.l) != 0,
          "re-HELLO: %u asked, %u answered", (unsigned)P.l.stats.tx_hellos, P.hellos);
    CHECK(P.points == 9 && P.max_count == 1 && !P.mismatches && P.nacked == 0,
          "after the restart: %u points, at most %u per frame (limit forgotten?)", P.points, P.max_count);
    peer_version = 0;
}

/* ---- reboots of a deterministic instrument (v1.2 4.1) ------------------ */

static uint8_t rb_put_entries[65536]; /* entries of the PUT sent with seq */
static struct {
    int cfg_acked, status_seen, hello_at_set;
    unsigned entries_acked, puts_acked, commit_acked, refused;
    uint32_t hello_ms;
} rb;
static uint32_t rb_boot_at;

static void rb_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *n)
{
    on_done(app, seq, type, code, n);
    if (code != 0) {
        rb.refused++;
        return;
    }
    if (type == IT2N_MSG_HELLO && !rb.hello_at_set) {
        rb.hello_ms = now_ms() - rb_boot_at;
        rb.hello_at_set = 1;
    } else if (type == IT2N_MSG_CONFIGURE)
        rb.cfg_acked = 1;
    else if (type == IT2N_MSG_PUT) {
        rb.entries_acked += rb_put_entries[seq];
        rb.puts_acked++;
    } else if (type == IT2N_MSG_COMMIT)
        rb.commit_acked = 1;
}

/* What a stalled boot was waiting for, and the daemon's last words then
 * (the log's tail at the end of the run is many boots later). */
static void stall_report(unsigned b, unsigned step, unsigned nsteps, unsigned kill_at, int late_frames)
{
    char cmd[400];
    const it2n_link_stats *st = &P.l.stats;
    fprintf(stderr,
            "stall: boot %u at step %u of %u (kill at %u, late frames %d): hello %d, status %d, configure %d, "
            "PUTs ACKed %u, commit %d, results %u; link: %u pending, session %08x, rto %u ms, retx %u, "
            "RCVD seen %u, foreign %u, resyncs %u, stall waits %u, HELLOs sent %u, answered %u\n",
            b, step, nsteps, kill_at, late_frames, rb.hello_at_set, rb.status_seen, rb.cfg_acked, rb.puts_acked,
            (int)rb.commit_acked, P.results, (unsigned)it2n_link_pending(&P.l), (unsigned)it2n_link_session(&P.l),
            (unsigned)it2n_link_rto(&P.l), (unsigned)st->tx_retx, (unsigned)st->rx_rcvd, (unsigned)st->rx_foreign,
            (unsigned)st->tx_resyncs, (unsigned)st->tx_stall_waits, (unsigned)st->tx_hellos, P.hellos);
    snprintf(cmd, sizeof cmd, "tail -30 '%s' | sed 's/^/stall: daemon: /' >&2", log_path);
    if (system(cmd) != 0)
        fprintf(stderr, "stall: (no daemon log)\n");
}

static void reboots(unsigned n, int v12, unsigned pct)
{
    static it2n_dataset ds[2];
    static it2n_model ref[2];
    static it2n_msg puts[2][40];
    unsigned nput[2] = {0, 0}, total = 0;
    it2n_errinfo e;
    const uint32_t rto = 100;
    unsigned complete = 0, killed = 0, lost = 0, stale = 0, stalls = 0, slow = 0, refused = 0, late = 0;
    unsigned checked = 0, max_hello = 0;
    unsigned phase[6] = {0, 0, 0, 0, 0, 0}; /* kills during HELLO, STATUS, CONFIGURE, PUTs, COMMIT, QUERYs */
    unsigned prev_acked = 0;
    int prev_cfg = 0, prev_killed = 0;
    uint32_t t0 = now_ms();
    for (int d = 0; d < 2; d++) {
        CHECK(synth_dataset(&ds[d], 3, 3, 0, d ? 2222u : 1111u, &e) == IT2N_OK, "synth");
        it2n_model_init(&ref[d]);
        CHECK(it2n_model_solve(&ref[d], &ds[d], &e) == IT2N_OK, "local solve");
        it2n_msg *m = &puts[d][0];
        memset(m, 0, sizeof *m);
        for (unsigned i = 0; i <= 3; i++)
            for (unsigned j = 0; j <= 3; j++)
                for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                    it2n_put_entry *en;
                    if (!(ds[d].present[i][j] & (1u << fp)))
                        continue;
                    if (m->u.put.count == 6) {
                        m = &puts[d][++nput[d]];
                        memset(m, 0, sizeof *m);
                    }
                    m->type = IT2N_MSG_PUT;
                    m->u.put.model = 3;
                    en = &m->u.put.e[m->u.put.count++];
                    en->i = (uint8_t)i;
                    en->j = (uint8_t)j;
                    en->fp = (uint8_t)fp;
                    it2n_dataset_get(&ds[d], i, j, fp, en->vals);
                    if (d == 0)
                        total++;
                }
        nput[d]++;
    }
    peer_version = v12 ? IT2N_PROTO_VERSION_12 : 0;
    for (unsigned b = 0; b < n && !failures; b++) {
        int set = (int)(b & 1u);
        /* steps: 0 HELLO, 1 STATUS, 2 CONFIGURE, 3.. PUTs, COMMIT, 2 QUERYs */
        unsigned nsteps = 3 + nput[set] + 3, step = 0;
        unsigned kill_at = rnd() % (nsteps + 4); /* >= nsteps: runs to the end */
        uint32_t kill_delay = rnd() % 3 ? rnd() % 12 : 0, step_at = 0;
        int late_frames = b > 0 && (rnd() & 1u) && prev_killed;
        static struct { uint16_t len; uint8_t b[IT2N_FRAME_MAX_WIRE + 64]; } keep[4];
        unsigned nkeep = 0;
        if (late_frames) {
            /* the dead boot's last frames, to arrive after the new HELLO */
            for (unsigned k = 0; k < 4 && k < nlast_out; k++) {
                unsigned at = (nlast_out - 1 - k) % 4;
                keep[nkeep].len = last_out[at].len;
                memcpy(keep[nkeep++].b, last_out[at].b, last_out[at].len);
            }
        }
        memset(&rb, 0, sizeof rb);
        peer_init(&P, 77, 0x1D, pct, rto); /* the same every boot */
        P.l.cfg.on_done = rb_done;
        P.ref = &ref[set];
        rb_boot_at = now_ms();
        uint32_t boot_t = now_ms(), progress = now_ms();
        int stalled = 0, done = 0;
        unsigned last_acked = 0;
        while (!done) {
            it2n_msg m;
            int can = 0;
            if (step < nsteps) {
                memset(&m, 0, sizeof m);
                if (step == 0) {
                    m = hello();
                    m.u.hello.version_min = m.u.hello.version_max =
                        v12 ? IT2N_PROTO_VERSION_12 : IT2N_PROTO_VERSION;
                    m.u.hello.window = 4;
                    can = 1;
                } else if (step == 1) {
                    m = model_msg(IT2N_MSG_GET_STATUS, 3);
                    can = rb.hello_at_set && P.hellos > 0;
                } else if (step == 2) {
                    m.type = IT2N_MSG_CONFIGURE;
                    m.u.configure.model = 3;
                    m.u.configure.n = 3;
                    m.u.configure.m = 3;
                    can = rb.status_seen && it2n_link_pending(&P.l) == 0;
                } else if (step < 3 + nput[set]) {
                    m = puts[set][step - 3];
                    can = rb.cfg_acked && it2n_link_can_send(&P.l);
                } else if (step == 3 + nput[set]) {
                    m = model_msg(IT2N_MSG_COMMIT, 3);
                    can = it2n_link_can_send(&P.l);
                } else {
                    memset(&m, 0, sizeof m);
                    m.type = IT2N_MSG_QUERY;
                    m.u.query.model = 3;
                    m.u.query.u = m.u.query.w = step == nsteps - 1 ? IT2N_WIRE_PAR_ONE / 3 : 0;
                    can = rb.commit_acked && it2n_link_can_send(&P.l);
                }
            }
            if (kill_at < nsteps && step > kill_at)
                can = 0; /* the power cut comes while this step is out */
            if (can) {
                int32_t seq = it2n_link_send(&P.l, &m, now_ms());
                CHECK(seq >= 0, "boot %u: send step %u: %d", b, step, (int)seq);
                if (seq < 0)
                    break;
                if (m.type == IT2N_MSG_PUT)
                    rb_put_entries[seq] = m.u.put.count;
                step++;
                step_at = now_ms();
                progress = now_ms();
            }
            pump(&P, can ? 0 : 2);
            if (step == 2 && !rb.status_seen && P.status.model == 3) {
                rb.status_seen = 1;
                /* what the previous boot got ACKed is all there */
                unsigned present = total - P.status.missing;
                checked++;
                if (prev_cfg && P.status.n == 3 && present < prev_acked)
                    lost += prev_acked - present;
            }
            if (late_frames && rb.hello_at_set && nkeep) {
                for (unsigned k = nkeep; k-- > 0;)
                    raw_write(keep[k].b, keep[k].len);
                nkeep = 0;
                late++;
            }
            if (P.acked != last_acked) {
                last_acked = P.acked;
                progress = now_ms();
            }
            if (kill_at < nsteps && step > kill_at && now_ms() - step_at >= kill_delay) {
                unsigned last = step - 1;
                killed++;
                phase[last < 3 ? last : last < 3 + nput[set] ? 3 : last == 3 + nput[set] ? 4 : 5]++;
                break; /* power cut: whatever is on the line stays there */
            }
            if (step == nsteps && it2n_link_pending(&P.l) == 0 && P.results >= 2) {
                complete++;
                CHECK(P.mismatches == 0, "boot %u: QUERY results differ from the data set's solve", b);
                stale += P.mismatches;
                done = 1;
            }
            if (now_ms() - progress > 3000) {
                stalled = 1; /* never a timeout: nothing moved for 3 s */
                if (v12) /* reboot11 stalls by design */
                    stall_report(b, step, nsteps, kill_at, late_frames);
                break;
            }
        }
        stalls += stalled;
        refused += rb.refused;
        if (rb.hello_at_set) {
            if (rb.hello_ms > max_hello)
                max_hello = rb.hello_ms;
            slow += pct == 0 && rb.hello_ms > 2 * rto + 200; /* one exchange + 2 RTO */
        } else if (stalled) {
            slow++;
        }
        (void)boot_t;
        prev_acked = rb.cfg_acked ? rb.entries_acked : 0;
        prev_killed = !done && !stalled;
        prev_cfg = rb.cfg_acked;
    }
    peer_version = 0;
    printf("%s%s: %u boots of a deterministic instrument (first seq 77%s): %u complete, %u killed (%u with "
           "frames arriving late), %u STATUS checks: %u ACKed entries lost, %u refused (DUPLICATE: stale), %u "
           "mismatching results, %u stalls, %u slow HELLOs (max %u ms, bound %u), %u ms; kills after sending "
           "HELLO %u, STATUS %u, CONFIGURE %u, a PUT %u, COMMIT %u, a QUERY %u\n",
           v12 ? "reboot (v1.2)" : "reboot11 (v1.1, fixed session id)", pct ? ", faults on the line" : "", n, v12 ? "" : ", session 0x1D", complete,
           killed, late, checked, lost, refused, stale, stalls, slow, max_hello, 2 * rto + 200, now_ms() - t0,
           phase[0], phase[1], phase[2], phase[3], phase[4], phase[5]);
    if (v12)
        CHECK(lost == 0 && refused == 0 && stale == 0 && stalls == 0 && slow == 0,
              "reboot: %u lost, %u refused, %u stale, %u stalls, %u slow", lost, refused, stale, stalls, slow);
    else
        CHECK(lost + refused + stale + stalls + slow > 0, "reboot11: the v1.1 handshake was expected to fail");
}

/* The example as a firmware would run it, twice (two boots exactly alike:
 * no session id, the same first sequence number 0; v1.2 gives each its
 * session, and the same points again are no DUPLICATE because CONFIGURE
 * clears them), each result checked against the core. */
static void doc(unsigned runs)
{
    static it2n_dataset ds;
    static it2n_model ref;
    it2n_errinfo e;
    it2n_point pt;
    it2n_dataset_init(&ds, 1, 1, IT2N_F_TYPE1, NULL);
    for (unsigned i = 0; i <= 1; i++)
        for (unsigned j = 0; j <= 1; j++) {
            it2n_val v[IT2N_CH_COUNT] = {(it2n_val)(10 * i) * IT2N_VAL_ONE, (it2n_val)(10 * j) * IT2N_VAL_ONE, 0,
                                         IT2N_VAL_ONE / 2 + (it2n_val)i * (IT2N_VAL_ONE / 4), IT2N_VAL_ONE / 8,
                                         IT2N_VAL_ONE / 4 - (it2n_val)j * (IT2N_VAL_ONE / 8)};
            it2n_dataset_put(&ds, i, j, IT2N_FP_D, v, false, &e);
        }
    it2n_model_init(&ref);
    CHECK(it2n_model_solve(&ref, &ds, &e) == IT2N_OK, "local solve");
    it2n_eval(&ref, it2n_par_from_wire(IT2N_WIRE_PAR_ONE / 2), it2n_par_from_wire(IT2N_WIRE_PAR_ONE / 2), &pt, NULL);
    for (unsigned k = 0; k < runs; k++) {
        it2n_val t = -1;
        it2n_msg_nack why;
        memset(&why, 0, sizeof why);
        int r = upload_and_query(&t, &why);
        printf("doc example (docs/instrument.md) run %u: %d, T(0.5, 0.5) = %.7f (core: %.7f)\n", k + 1, r,
               (double)t / 16777216.0, (double)pt.v[IT2N_FP_D][IT2N_CH_T] / 16777216.0);
        CHECK(r == 0 && t == pt.v[IT2N_FP_D][IT2N_CH_T], "doc example: %d (NACK code %d at %d,%d)", r, why.code,
              why.i, why.j);
    }
}
#else
static void doc(unsigned runs)
{
    (void)runs;
    fprintf(stderr, "daemon_link: built without the docs/instrument.md example\n");
    failures++;
}
#endif

int main(int argc, char **argv)
{
    if (argc < 4 || (argc - 2) % 2) {
        fprintf(stderr, "usage: daemon_link IT2ND SCENARIO ARG [SCENARIO ARG ...]\n");
        return 2;
    }
    it2nd = argv[1];
    signal(SIGPIPE, SIG_IGN);
    rng ^= (uint64_t)getpid() << 20;
    setup(getenv("LINK_EXTRA") ? getenv("LINK_EXTRA") : "rto_ms = 30\n");
    wait_link();
    for (int k = 2; k + 1 < argc && !failures; k += 2) {
        unsigned v = (unsigned)atoi(argv[k + 1]);
        if (!strcmp(argv[k], "sessions"))
            sessions(v);
        else if (!strcmp(argv[k], "kill"))
            kills(v);
        else if (!strcmp(argv[k], "lossy"))
            lossy(v);
        else if (!strcmp(argv[k], "wide"))
            wide(v);
        else if (!strcmp(argv[k], "spec"))
            spec(v);
        else if (!strcmp(argv[k], "doc"))
            doc(v);
        else if (!strcmp(argv[k], "reboot"))
            reboots(v, 1, 0);
        else if (!strcmp(argv[k], "rebootlossy"))
            reboots(v, 1, 5);
        else if (!strcmp(argv[k], "relimit"))
            relimit(v);
        else if (!strcmp(argv[k], "lossy12")) {
            peer_version = IT2N_PROTO_VERSION_12; /* the same with a v1.2 peer */
            lossy(v);
            peer_version = 0;
        } else if (!strcmp(argv[k], "kill12")) {
            peer_version = IT2N_PROTO_VERSION_12; /* the same with a v1.2 peer */
            kills(v);
            peer_version = 0;
        }
        else if (!strcmp(argv[k], "reboot11"))
            reboots(v, 0, 0);
        else {
            fprintf(stderr, "unknown scenario %s\n", argv[k]);
            return 2;
        }
    }
    if (failures) {
        fprintf(stderr, "daemon_link: %d check(s) failed; daemon log %s:\n", failures, log_path);
        char cmd[400];
        snprintf(cmd, sizeof cmd, "tail -20 '%s' >&2", log_path);
        if (system(cmd) != 0)
            fprintf(stderr, "(no log)\n");
    }
    return failures ? 1 : 0;
}
