/* links.c — see links.h. The protocol application of the daemon side
 * (protocol v1.2 and v1.1, docs/protocol.md):
 *   HELLO       version check (NACK VERSION without a common version), the
 *               peer's window and max_payload applied, ACK, then the
 *               daemon's own HELLO (type HELLO); a v1.2 peer's HELLO gets
 *               a new session id (links_new_session), carried by our HELLO
 *               and every later frame of that session
 *   CONFIGURE   (re)start collecting the model (clears its points); v1.3:
 *               the 5-byte form names the kind, which must be the
 *               model's configured one (NACK INVAL otherwise)
 *   PUT         all entries or none; REPLACE flag honoured; an entry equal
 *               to the stored one is an idempotent success (exactly once
 *               across restarts)
 *   COMMIT      solve; RESET clear (0xFF: every model)
 *   GET_STATUS / QUERY / LOCATE   ACK, then the response frame
 * Data messages are ACKed only after the WAL commit (links_release); a
 * refused one is NACKed at once with the core's error detail and changed
 * nothing. SAMPLE and GET_NET are ACKed and answered by a run of
 * SAMPLE_DATA / NET_ROW frames, produced as the send window frees. One
 * response (run) at a time; requests arriving meanwhile wait unanswered in
 * a queue (at most the peer's window) and are served in order after it —
 * never NACKed BUSY within the window (a frame over it is refused BUSY by
 * the link, protocol.md 4.3 rule 3). Our frames are retransmitted with backoff until the
 * peer answers or the link is declared down (peer_timeout_ms); then they
 * are dropped and the peer session, when it speaks again, gets EVENT LOST
 * (if it said HELLO; a new session does not: the frames were not its). */
#include "links.h"

#include <errno.h>
#include <stdlib.h>
#include <sys/random.h>
#include <string.h>
#include <unistd.h>

#include "it2n_link.h"
#include "link_serial.h"
#include "link_usb.h"
#include "errs.h"
#include "log.h"
#include "loop.h"
#include "models.h"
#include "store.h"

/* ACKs waiting for the WAL: each is a delivery the link still awaits an
 * answer for, and the link delivers none while the frame a window before
 * it awaits one (protocol.md 4.3 rule 3): at most our window per peer
 * session (held ACKs of an earlier session are forgotten, see on_rx). */
#define HELD_MAX IT2N_PROTO_WINDOW
/* EVENTs waiting for the send window: one per model at most (the latest),
 * so a slow peer costs bounded memory and never stalls the loop. */
#define EVQ_MAX 64
/* Serial output queue: whole encoded frames waiting for the tty. Room for
 * the send window plus answers and a retransmission round; a frame that
 * does not fit is dropped whole (never a part of one), and new reliable
 * messages wait (links_can_send) until a frame's worth is free. */
#define OUTQ_SIZE (6u * IT2N_FRAME_MAX_WIRE)
/* Most nodes one SAMPLE may ask for (protocol.md 5.8). */
#define IT2N_SAMPLE_NODES_MAX 65536u

struct link {
    struct conf_link cfg;
    int fd;               /* serial; -1 when closed        */
    int tty;              /* fd is a tty (VMIN 0: read 0 = no data) */
    struct usb_link *usb; /* usb; NULL when closed         */
    int up;
    it2n_link pl;
    it2n_ostream os;
    uint16_t held[HELD_MAX];       /* seqs whose ACK waits for the commit */
    uint64_t held_batch[HELD_MAX]; /* the WAL batch each waits for */
    int nheld;
    uint32_t held_sessions; /* pl.stats.rx_sessions the held ACKs belong to */
    long held_down_timer;   /* reopen after an impossible hold overflow */
    unsigned backoff_ms;
    long retry_timer, poll_timer;
    uint32_t poll_due;     /* when poll_timer fires (ms, now32) */
    uint32_t entries;      /* entries accepted, for logs   */
    uint32_t entries_idem; /* entries re-sent as stored: no effect */
    /* A multi-frame response (SAMPLE_DATA or NET_ROW run) still to send,
     * produced lazily as the send window frees. */
    struct {
        int kind; /* 0 none, IT2N_MSG_SAMPLE or IT2N_MSG_GET_NET */
        uint16_t re, rows, cols;
        uint8_t model, fp;
        uint32_t next, total;
    } job;
    it2n_msg rsp; /* a single response waiting for the window */
    int has_rsp;
    /* Requests waiting for the response (run) before them: unanswered,
     * so the peer's window bounds the queue. */
    struct {
        uint16_t seq;
        it2n_msg req;
    } rq[IT2N_PROTO_WINDOW];
    int nrq;
    uint32_t lost;         /* frames dropped when declared down, to report */
    uint32_t lost_session; /* ... to this peer session (it2n_link_session) */
    uint32_t rto_ms;
    int peer;               /* a HELLO came from the peer since the open */
    uint32_t hello_session; /* ... in this peer session (EVENTs go to it) */
    int hello_due;          /* our HELLO answer waits for room in the window */
    it2n_msg_event evq[EVQ_MAX];
    int nev;
    uint32_t ev_sent, ev_merged;
    /* Output: the frame being encoded (it2n_frame_write hands it over in
     * blocks, delimiter last), then the queue of whole frames for the tty,
     * written from out[out_off] up to out_len, the rest on POLLOUT. */
    uint8_t stage[IT2N_FRAME_MAX_WIRE];
    size_t nstage;
    int stage_bad; /* frame longer than the stage: dropped */
    uint8_t out[OUTQ_SIZE];
    size_t out_off, out_len;
    int pollout;    /* POLLOUT armed on fd */
    int hold_flush; /* frames queued, written at the end of
                                 the input or release being handled */
    struct links_out_stats st;
};

static struct link *links;
static int nlinks;
static int backoff_max_ms;

static uint32_t now32(void)
{
    return (uint32_t)loop_now_ms();
}

static void link_open(void *arg);

static size_t out_room(const struct link *l)
{
    return OUTQ_SIZE - (l->out_len - l->out_off);
}

/* Write queued frames until the queue is empty or the tty is full; POLLOUT
 * is armed while anything is left. Never blocks. 0, or -1 on an I/O error
 * (the caller takes the link down). */
static int out_flush(struct link *l)
{
    while (l->out_off < l->out_len) {
        ssize_t n = write(l->fd, l->out + l->out_off, l->out_len - l->out_off);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            if (!l->pollout) {
                l->pollout = 1;
                l->st.blocked++;
                loop_mod_fd(l->fd, POLLIN | POLLOUT);
            }
            return 0;
        }
        if (n <= 0)
            return -1;
        l->out_off += (size_t)n;
    }
    l->out_off = l->out_len = 0;
    if (l->pollout) {
        l->pollout = 0;
        loop_mod_fd(l->fd, POLLIN);
    }
    return 0;
}

/* A whole frame is in the stage: hand it to USB in one transfer, or queue
 * it for the tty (dropped whole when the queue is full: a reliable frame
 * is retransmitted, a lost ACK is answered again on the retransmission). */
static int frame_out(struct link *l)
{
    size_t n = l->nstage;
    int bad = l->stage_bad;
    l->nstage = 0;
    l->stage_bad = 0;
    if (bad) {
        l->st.dropped++;
        return 0;
    }
    l->st.frames++;
    if (l->cfg.type == CONF_LINK_USB)
        return link_usb_write(l->usb, l->stage, n);
    if (out_room(l) < n) {
        l->st.dropped++;
        log_debug("link %s: output queue full; %zu-byte frame dropped", l->cfg.name, n);
        return 0;
    }
    if (OUTQ_SIZE - l->out_len < n) { /* compact: free room is at the front */
        memmove(l->out, l->out + l->out_off, l->out_len - l->out_off);
        l->out_len -= l->out_off;
        l->out_off = 0;
    }
    memcpy(l->out + l->out_len, l->stage, n);
    l->out_len += n;
    return l->pollout || l->hold_flush ? 0 : out_flush(l);
}

/* Frames produced while handling one input chunk or one WAL release (the
 * ACKs of a group commit, answers, EVENTs) go out in one write(), not one
 * each: fewer system calls, and the peer wakes up once. */
static void flush_begin(struct link *l)
{
    l->hold_flush = 1;
}

static void pump_job(struct link *l);
static void link_down(struct link *l, const char *why);

static void flush_end(struct link *l)
{
    l->hold_flush = 0;
    if (!l->up || l->fd < 0 || l->pollout || l->out_off == l->out_len)
        return;
    if (out_flush(l) < 0) {
        link_down(l, strerror(errno));
        return;
    }
    pump_job(l); /* a response waiting for queue room may go on */
}

/* Output stream (contract in it2n_stream.h): it2n_frame_write hands over
 * one frame as COBS blocks, which never contain 0x00, then the delimiter
 * 0x00. Blocks are collected in the stage and the frame goes out whole, so
 * a full tty never cuts a frame (security finding 7). */
static int os_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    struct link *l = s->state;
    if (!l->up)
        return -1;
    if (len > sizeof l->stage - l->nstage)
        l->stage_bad = 1;
    else
        memcpy(l->stage + l->nstage, buf, len);
    if (!l->stage_bad)
        l->nstage += len;
    if (buf[len - 1] != 0)
        return 0;
    return frame_out(l);
}

/* A new reliable message may go out: window slot free and room in the
 * output queue for a frame of any size. Otherwise the caller waits (the
 * job or EVENT stays queued; a request answers BUSY). */
static int can_send(const struct link *l)
{
    return l->up && it2n_link_can_send(&l->pl) && out_room(l) >= IT2N_FRAME_MAX_WIRE;
}

static void link_down(struct link *l, const char *why)
{
    if (!l->up && l->retry_timer)
        return;
    log_warn("link %s: %s; reopening in %u ms", l->cfg.name, why, l->backoff_ms);
    if (l->fd >= 0) {
        loop_del_fd(l->fd);
        close(l->fd);
        l->fd = -1;
    }
    if (l->usb) {
        link_usb_close(l->usb);
        l->usb = NULL;
    }
    l->up = 0;
    l->nheld = 0; /* never ACKed: the instrument retransmits */
    if (l->held_down_timer) {
        loop_cancel_timer(l->held_down_timer);
        l->held_down_timer = 0;
    }
    if (l->poll_timer)
        loop_cancel_timer(l->poll_timer);
    l->poll_timer = 0;
    l->retry_timer = loop_add_timer(l->backoff_ms, link_open, l);
    l->backoff_ms = l->backoff_ms * 2 > (unsigned)backoff_max_ms ? (unsigned)backoff_max_ms : l->backoff_ms * 2;
}

static void held_overflow_down(void *arg)
{
    struct link *l = arg;
    l->held_down_timer = 0;
    link_down(l, "more deliveries awaiting the WAL than the window allows");
}

/* ACK seq once WAL batch `batch` is durable (links_release_upto). */
static void hold(struct link *l, uint16_t seq, uint64_t batch)
{
    if (l->nheld < HELD_MAX) {
        l->held_batch[l->nheld] = batch;
        l->held[l->nheld++] = seq;
        return;
    }
    /* Cannot happen (HELD_MAX): never drop an ACK silently. Reopen the
     * link; the peer resends what was not ACKed (exactly once: 4.3). */
    log_err("link %s: seq %u: %d ACKs already wait for the WAL (window %u): internal error, reopening the link",
            l->cfg.name, seq, l->nheld, (unsigned)it2n_link_window(&l->pl));
    if (!l->held_down_timer)
        l->held_down_timer = loop_add_timer(0, held_overflow_down, l);
}

/* Frames the daemon keeps in flight towards the peer: what its RTO covers.
 * links_rto_ms is the time IT2N_PROTO_WINDOW_MIN + 1 maximal frames take on
 * a serial line, plus 50 ms: a wider window would have its last frames
 * retransmitted while still queued on the line. USB and an unpaced (baud
 * 0) link: the negotiated window. */
static unsigned send_window_cap(const struct link *l)
{
    uint64_t frame_ms1000, n;
    if (l->cfg.type == CONF_LINK_USB || l->cfg.baud <= 0 || l->rto_ms <= 50u)
        return l->cfg.type == CONF_LINK_USB || l->cfg.baud <= 0 ? IT2N_PROTO_WINDOW : IT2N_PROTO_WINDOW_MIN;
    frame_ms1000 = (uint64_t)IT2N_FRAME_MAX_WIRE * 10u * 1000u * 1000u / (uint64_t)l->cfg.baud;
    n = (uint64_t)(l->rto_ms - 50u) * 1000u / (frame_ms1000 ? frame_ms1000 : 1u);
    n = n > 1u ? n - 1u : 0u;
    return n < IT2N_PROTO_WINDOW_MIN ? IT2N_PROTO_WINDOW_MIN : n > IT2N_PROTO_WINDOW ? IT2N_PROTO_WINDOW : (unsigned)n;
}

static void send_hello(struct link *l)
{
    it2n_msg m;
    /* A window full of frames for a previous peer (v1.1 sends them on to
     * the new session) must not swallow the answer: it goes out first
     * when there is room (pump_events), and a client waiting for our caps
     * (BSPLINE, FINE) gets them. */
    if (!can_send(l)) {
        l->hello_due = 1;
        return;
    }
    l->hello_due = 0;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_HELLO;
    m.u.hello.version_min = IT2N_PROTO_VERSION_MIN;
    m.u.hello.version_max = IT2N_PROTO_VERSION_MAX;
    m.u.hello.max_degree = IT2N_MAX_DEGREE;
    m.u.hello.window = it2n_link_window(&l->pl); /* what we accept in flight */
    m.u.hello.caps = IT2N_CAP_SERVER | IT2N_CAP_Z | IT2N_CAP_CHORD | IT2N_CAP_TYPE1 | IT2N_CAP_EVENTS |
                     IT2N_CAP_BSPLINE | /* v1.3 messages: the B-spline CONFIGURE */
                     IT2N_CAP_FINE;     /* ... and PUT FINE (Q30 memberships) */
    m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
    m.u.hello.max_models = (uint16_t)models_count(); /* ids served (configured) */
    memcpy(m.u.hello.node, "it2nd", 5);
    it2n_link_send(&l->pl, &m, now32());
}

static int model_state(const struct model *md)
{
    switch (md->state) {
    case IT2N_REGMAP_STATE_SOLVED: return IT2N_MS_SOLVED;
    case IT2N_REGMAP_STATE_INCOMPLETE: return IT2N_MS_COLLECTING;
    case IT2N_REGMAP_STATE_FAILED: return IT2N_MS_ERROR;
    default: return IT2N_MS_EMPTY;
    }
}

/* SAMPLE_DATA points per frame: as many as the peer's max_payload takes. */
static uint32_t sample_per_frame(const struct link *l)
{
    uint32_t k = (it2n_link_max_payload(&l->pl) - IT2N_SAMPLE_HDR) / IT2N_SAMPLE_POINT;
    return k < IT2N_SAMPLE_MAX ? k : IT2N_SAMPLE_MAX;
}

static void serve_queue(struct link *l);
static void pump_rsp(struct link *l);
static void on_poll(void *arg);

/* (Re)arm the retransmission timer for the link's next deadline when the
 * armed one would fire later (a frame just sent with a short RTO): at
 * most 100 ms, at least 5 ms ahead. */
static void arm_poll(struct link *l)
{
    uint32_t now = now32(), next = it2n_link_next_timeout(&l->pl, now);
    if (!l->up)
        return;
    next = next < 5 ? 5 : next > 100 ? 100 : next;
    if (l->poll_timer && (int32_t)(l->poll_due - (now + next)) <= 0)
        return; /* the armed timer comes soon enough */
    if (l->poll_timer)
        loop_cancel_timer(l->poll_timer);
    l->poll_due = now + next;
    l->poll_timer = loop_add_timer(next, on_poll, l);
}

/* Send the queued EVENTs that fit the window, oldest first. */
static void pump_events(struct link *l)
{
    if (l->hello_due)
        send_hello(l);
    while (!l->hello_due && l->nev && can_send(l)) {
        it2n_msg m;
        memset(&m, 0, sizeof m);
        m.type = IT2N_MSG_EVENT;
        m.u.event = l->evq[0];
        memmove(l->evq, l->evq + 1, (size_t)(l->nev - 1) * sizeof l->evq[0]);
        l->nev--;
        if (it2n_link_send(&l->pl, &m, now32()) >= 0)
            l->ev_sent++;
    }
}

/* Send what fits of the current SAMPLE / GET_NET job (after the EVENTs),
 * then start the next queued request once the response is out. */
static void pump_job(struct link *l)
{
    pump_events(l);
    pump_rsp(l);
    serve_queue(l);
    arm_poll(l);
}

static void pump_rsp(struct link *l)
{
    if (l->has_rsp && can_send(l)) {
        l->has_rsp = 0;
        it2n_link_send(&l->pl, &l->rsp, now32());
    }
    while (!l->has_rsp && l->job.kind && can_send(l)) {
        struct model *md = models_by_id(l->job.model);
        if (md)
            md = models_view(md);
        it2n_msg m;
        memset(&m, 0, sizeof m);
        if (!md || md->state != IT2N_REGMAP_STATE_SOLVED) {
            log_info("link %s: model %u changed state; response cut short", l->cfg.name, l->job.model);
            l->job.kind = 0;
            return;
        }
        if (l->job.kind == IT2N_MSG_SAMPLE) {
            it2n_msg_sample_data *d = &m.u.sample_data;
            uint32_t left = l->job.total - l->job.next;
            m.type = IT2N_MSG_SAMPLE_DATA;
            d->re = l->job.re;
            d->model = l->job.model;
            d->fp = l->job.fp;
            d->rows = l->job.rows;
            d->cols = l->job.cols;
            d->start = l->job.next;
            d->count = (uint8_t)(left < sample_per_frame(l) ? left : sample_per_frame(l));
            for (unsigned k = 0; k < d->count; k++) {
                uint32_t idx = d->start + k, r = idx / d->cols, c = idx % d->cols;
                it2n_point pt;
                it2n_par u = (it2n_par)(((uint64_t)r << IT2N_PAR_FRAC) / (d->rows - 1u));
                it2n_par w = (it2n_par)(((uint64_t)c << IT2N_PAR_FRAC) / (d->cols - 1u));
                if (models_eval(md, u, w, &pt, NULL) != IT2N_OK) {
                    l->job.kind = 0;
                    return;
                }
                memcpy(d->v[k], pt.v[l->job.fp], sizeof d->v[k]);
            }
            l->job.next += d->count;
        } else {
            it2n_msg_net_row *d = &m.u.net_row;
            m.type = IT2N_MSG_NET_ROW;
            d->re = l->job.re;
            d->model = l->job.model;
            d->fp = l->job.fp;
            d->n = md->mdl.n;
            d->m = md->mdl.m;
            d->row = (uint8_t)l->job.next;
            for (unsigned j = 0; j <= d->m; j++)
                for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++)
                    d->v[j][ch] = it2n_model_ctrl(&md->mdl, d->row, j, l->job.fp, ch);
            l->job.next++;
        }
        if (it2n_link_send(&l->pl, &m, now32()) < 0) {
            l->job.kind = 0;
            return;
        }
        if (l->job.next >= l->job.total)
            l->job.kind = 0;
    }
}

/* NACK with detail now; the callback's answer is then DEFER. */
static int refuse(struct link *l, uint16_t seq, int code, const it2n_errinfo *err)
{
    log_info("link %s: seq %u refused: %s", l->cfg.name, seq, errs_strerror(code));
    it2n_link_complete(&l->pl, seq, code, err);
    return IT2N_LINK_DEFER;
}

static it2n_errinfo detail(int code, int64_t value, int64_t lo, int64_t hi)
{
    it2n_errinfo e;
    memset(&e, 0, sizeof e);
    e.code = code;
    e.i = e.j = -1;
    e.fp = e.ch = -1;
    e.value = value;
    e.lo = lo;
    e.hi = hi;
    return e;
}

/* Unknown model id: NACK MODEL, value = the id asked for. */
static int refuse_model(struct link *l, uint16_t seq, unsigned id)
{
    it2n_errinfo e = detail(IT2N_PROTO_ERR_MODEL, id, 0, IT2N_MODEL_ALL - 1);
    return refuse(l, seq, IT2N_PROTO_ERR_MODEL, &e);
}

/* A response of `size` bytes the peer announced it cannot take. */
static int too_big(struct link *l, uint16_t seq, size_t size)
{
    it2n_errinfo e = detail(IT2N_PROTO_ERR_NOSPACE, (int64_t)size, 0, it2n_link_max_payload(&l->pl));
    return refuse(l, seq, IT2N_PROTO_ERR_NOSPACE, &e);
}

/* SAMPLE / GET_NET: check, ACK, start the job. */
static int start_job(struct link *l, uint16_t seq, int kind, uint8_t model, uint8_t fp, uint16_t rows, uint16_t cols)
{
    struct model *md = models_by_id(model);
    /* Checks in the order of protocol.md 5.8: the request alone (its size),
     * then the model (MODEL), its state (STATE), its footprints (INVAL). */
    if (kind == IT2N_MSG_SAMPLE && (uint32_t)rows * cols > IT2N_SAMPLE_NODES_MAX) {
        /* bound the work one request can cause: value = nodes asked for */
        it2n_errinfo e = detail(IT2N_ERR_RANGE, (int64_t)rows * cols, 4, IT2N_SAMPLE_NODES_MAX);
        return refuse(l, seq, IT2N_ERR_RANGE, &e);
    }
    if (!md)
        return refuse_model(l, seq, model);
    md = models_view(md);
    if (md->state != IT2N_REGMAP_STATE_SOLVED)
        return IT2N_ERR_STATE;
    if (!models_has_fp(md, fp)) {
        it2n_errinfo e = detail(IT2N_ERR_INVAL, fp, IT2N_FP_D, IT2N_FP_D);
        e.fp = (int8_t)fp;
        return refuse(l, seq, IT2N_ERR_INVAL, &e); /* type-1: only D */
    }
    if (kind == IT2N_MSG_GET_NET && md->kind != MODEL_BEZIER) {
        /* NET_ROW carries a Bezier control net (up to 8 x 8): B-spline
         * coefficients are read over Modbus (paged, docs/registers.md). */
        it2n_errinfo e = detail(IT2N_ERR_INVAL, md->kind, MODEL_BEZIER, MODEL_BEZIER);
        return refuse(l, seq, IT2N_ERR_INVAL, &e);
    }
    if (kind == IT2N_MSG_GET_NET &&
        IT2N_NET_ROW_HDR + IT2N_SAMPLE_POINT * (md->mdl.m + 1u) > it2n_link_max_payload(&l->pl))
        return too_big(l, seq, IT2N_NET_ROW_HDR + IT2N_SAMPLE_POINT * (md->mdl.m + 1u));
    it2n_link_complete(&l->pl, seq, 0, NULL);
    l->job.kind = kind;
    l->job.re = seq;
    l->job.model = model;
    l->job.fp = fp;
    l->job.rows = rows;
    l->job.cols = cols;
    l->job.next = 0;
    l->job.total = kind == IT2N_MSG_SAMPLE ? (uint32_t)rows * cols : md->mdl.n + 1u;
    return IT2N_LINK_DEFER;
}

/* ACK now, then send a response. */
static int respond(struct link *l, uint16_t seq, const it2n_msg *rsp, size_t size)
{
    if (size > it2n_link_max_payload(&l->pl))
        return too_big(l, seq, size);
    it2n_link_complete(&l->pl, seq, 0, NULL);
    l->rsp = *rsp;
    l->has_rsp = 1;
    return IT2N_LINK_DEFER;
}

/* PUT entries not already stored with exactly these values: an entry equal
 * to the stored one has had its effect (a re-sent PUT whose ACK was lost,
 * e.g. across a restart of either side) and is skipped. */
static void put_fresh(const struct model *md, const it2n_msg_put *p, it2n_msg_put *out)
{
    *out = *p;
    out->count = 0;
    for (unsigned k = 0; k < p->count; k++) {
        const it2n_put_entry *e = &p->e[k];
        it2n_val have[IT2N_CH_COUNT];
        if (models_point_present(md, e->i, e->j, e->fp)) {
            /* compared in the layout sent: Q30 memberships with FINE */
            if (p->flags & IT2N_PUT_FINE)
                models_point_get_fine(md, e->i, e->j, e->fp, have);
            else
                models_point_get(md, e->i, e->j, e->fp, have);
            if (!(models_flags(md) & IT2N_F_Z))
                have[IT2N_CH_Z] = e->vals[IT2N_CH_Z]; /* z of a model without z: see do_put */
            if (!memcmp(have, e->vals, sizeof have))
                continue;
        }
        out->e[out->count++] = *e;
    }
}

static int do_put(struct link *l, uint16_t seq, struct model *md, const it2n_msg_put *p)
{
    struct model_txn t;
    it2n_errinfo err;
    it2n_msg_put fresh;
    int rc = IT2N_OK;
    if (p->flags & ~IT2N_PUT_FLAGS) { /* unknown flag bits: refused (protocol.md 5.4) */
        it2n_errinfo e = detail(IT2N_PROTO_ERR_FIELD, p->flags, 1, IT2N_PUT_FLAGS);
        return refuse(l, seq, IT2N_PROTO_ERR_FIELD, &e);
    }
    for (unsigned k = 0; k < p->count; k++) {
        const it2n_put_entry *e = &p->e[k];
        if (!(models_flags(md) & IT2N_F_Z) && e->vals[IT2N_CH_Z] != 0) {
            /* z given for a model without z: refused, never dropped */
            it2n_errinfo ez = detail(IT2N_ERR_RANGE, e->vals[IT2N_CH_Z], 0, 0);
            ez.i = e->i;
            ez.j = e->j;
            ez.fp = (int8_t)e->fp;
            ez.ch = IT2N_CH_Z;
            return refuse(l, seq, IT2N_ERR_RANGE, &ez);
        }
        if ((models_flags(md) & IT2N_F_TYPE1) && e->fp != IT2N_FP_D) {
            /* type-1 model: footprint D (3) only; lo..hi = 3..3 */
            it2n_errinfo et = detail(IT2N_ERR_INVAL, e->fp, IT2N_FP_D, IT2N_FP_D);
            et.i = e->i;
            et.j = e->j;
            et.fp = (int8_t)e->fp;
            return refuse(l, seq, IT2N_ERR_INVAL, &et);
        }
        if (e->i > models_n(md) || e->j > models_m(md)) {
            it2n_errinfo ei = detail(IT2N_ERR_INVAL, e->i > models_n(md) ? e->i : e->j, 0,
                                     e->i > models_n(md) ? models_n(md) : models_m(md));
            ei.i = e->i;
            ei.j = e->j;
            ei.fp = (int8_t)e->fp;
            return refuse(l, seq, IT2N_ERR_INVAL, &ei);
        }
    }
    if (!(p->flags & IT2N_PUT_REPLACE)) {
        put_fresh(md, p, &fresh);
        if (fresh.count == 0) {
            /* Every entry already stored as sent: success, no effect. ACK
             * once what is stored is durable. */
            l->entries_idem += p->count;
            log_info("link %s: PUT seq %u: all %u entries already stored with these values (a re-sent PUT): "
                     "success, no effect",
                     l->cfg.name, seq, p->count);
            if (store_degraded())
                return refuse(l, seq, IT2ND_ERR_IO, NULL);
            if (store_pending())
                hold(l, seq, store_batch());
            else if (store_busy())
                hold(l, seq, store_batch() - 1);
            else
                return 0;
            return IT2N_LINK_DEFER;
        }
        if (fresh.count < p->count)
            log_info("link %s: PUT seq %u: %u of %u entries already stored with these values (a re-sent PUT): "
                     "no effect",
                     l->cfg.name, seq, p->count - fresh.count, p->count);
        l->entries_idem += (uint32_t)(p->count - fresh.count);
        p = &fresh;
    }
    models_txn_begin(&t);
    /* FINE (v1.3): memberships in Q30, stored as sent (what 'it2n' reads
     * from the same CSV); else Q24, stored exactly (x 2^6) */
    for (unsigned k = 0; k < p->count && rc == IT2N_OK; k++)
        rc = (p->flags & IT2N_PUT_FINE) ? models_put_fine(md, p->e[k].i, p->e[k].j, p->e[k].fp, p->e[k].vals,
                                                          (p->flags & IT2N_PUT_REPLACE) != 0, &err)
                                        : models_put(md, p->e[k].i, p->e[k].j, p->e[k].fp, p->e[k].vals,
                                                     (p->flags & IT2N_PUT_REPLACE) != 0, &err);
    if (rc != IT2N_OK) {
        /* All or nothing: the model and the WAL queue go back. */
        it2n_errinfo keep = md->last_err;
        models_txn_rollback(&t);
        md->last_err = keep;
        if (rc == IT2N_ERR_MISSING)
            err.ch = -1;
        return refuse(l, seq, rc, &err);
    }
    models_txn_commit(&t);
    l->entries += p->count;
    hold(l, seq, store_batch());
    return IT2N_LINK_DEFER;
}

/* A query-type request (GET_STATUS, QUERY, LOCATE, SAMPLE, GET_NET):
 * answered now (ACK + response, or NACK). Returns as on_rx does. */
static int serve(struct link *l, uint16_t seq, const it2n_msg *msg)
{
    struct model *md = NULL;
    it2n_msg rsp;
    int rc;
    memset(&rsp, 0, sizeof rsp);
    switch (msg->type) {
    case IT2N_MSG_GET_STATUS:
        md = models_by_id(msg->u.model.model);
        if (!md)
            return refuse_model(l, seq, msg->u.model.model);
        md = models_view(md); /* readers: the last durable state */
        rsp.type = IT2N_MSG_STATUS;
        rsp.u.status.re = seq;
        rsp.u.status.model = (uint8_t)md->id;
        rsp.u.status.state = (uint8_t)model_state(md);
        rsp.u.status.n = (uint8_t)models_n(md);
        rsp.u.status.m = (uint8_t)models_m(md);
        rsp.u.status.flags = (uint8_t)models_flags(md);
        /* u16 on the wire: a B-spline grid may lack more (saturated) */
        rsp.u.status.missing = (uint16_t)(models_missing(md) > 0xFFFFu ? 0xFFFFu : models_missing(md));
        rsp.u.status.generation = md->gen;
        rsp.u.status.last_error = (int16_t)md->last_err.code;
        return respond(l, seq, &rsp, 15);
    case IT2N_MSG_QUERY: {
        it2n_point pt;
        md = models_by_id(msg->u.query.model);
        if (!md)
            return refuse_model(l, seq, msg->u.query.model);
        md = models_view(md); /* readers: the last durable state */
        if (md->state != IT2N_REGMAP_STATE_SOLVED)
            return IT2N_ERR_STATE;
        if (447 > it2n_link_max_payload(&l->pl))
            return too_big(l, seq, 447);
        rc = models_eval(md, it2n_par_from_wire(msg->u.query.u), it2n_par_from_wire(msg->u.query.w), &pt, NULL);
        if (rc)
            return rc;
        rsp.type = IT2N_MSG_QUERY_RESULT;
        rsp.u.query_result.re = seq;
        rsp.u.query_result.model = (uint8_t)md->id;
        rsp.u.query_result.u = msg->u.query.u;
        rsp.u.query_result.w = msg->u.query.w;
        rsp.u.query_result.out_of_range = pt.out_of_range;
        memcpy(rsp.u.query_result.v, pt.v, sizeof pt.v);
        rsp.u.query_result.sum = pt.sum;
        return respond(l, seq, &rsp, 447);
    }
    case IT2N_MSG_LOCATE: {
        it2n_locate_result lr;
        md = models_by_id(msg->u.locate.model);
        if (!md)
            return refuse_model(l, seq, msg->u.locate.model);
        md = models_view(md); /* readers: the last durable state */
        if (md->state != IT2N_REGMAP_STATE_SOLVED)
            return IT2N_ERR_STATE;
        if (474 > it2n_link_max_payload(&l->pl))
            return too_big(l, seq, 474);
        rc = models_locate(md, msg->u.locate.x, msg->u.locate.y, &lr, NULL);
        if (rc)
            return rc;
        rsp.type = IT2N_MSG_LOCATE_RESULT;
        rsp.u.locate_result.re = seq;
        rsp.u.locate_result.model = (uint8_t)md->id;
        rsp.u.locate_result.x = msg->u.locate.x;
        rsp.u.locate_result.y = msg->u.locate.y;
        for (int fp = 0; fp < IT2N_FP_COUNT; fp++) {
            it2n_locate_wire *w = &rsp.u.locate_result.fp[fp];
            w->u = it2n_par_to_wire(lr.fp[fp].u);
            w->w = it2n_par_to_wire(lr.fp[fp].w);
            w->status = lr.fp[fp].status;
            w->residual = lr.fp[fp].residual;
            memcpy(w->v, lr.fp[fp].v, sizeof w->v);
        }
        return respond(l, seq, &rsp, 474);
    }
    case IT2N_MSG_SAMPLE:
        return start_job(l, seq, IT2N_MSG_SAMPLE, msg->u.sample.model, msg->u.sample.fp, msg->u.sample.rows,
                         msg->u.sample.cols);
    default: /* IT2N_MSG_GET_NET */
        return start_job(l, seq, IT2N_MSG_GET_NET, msg->u.get_net.model, msg->u.get_net.fp, 0, 0);
    }
}

/* Queued requests, in order, once no response is in progress. */
static void serve_queue(struct link *l)
{
    while (l->nrq && !l->job.kind && !l->has_rsp) {
        uint16_t seq = l->rq[0].seq;
        it2n_msg req = l->rq[0].req;
        int r;
        memmove(l->rq, l->rq + 1, (size_t)(l->nrq - 1) * sizeof l->rq[0]);
        l->nrq--;
        r = serve(l, seq, &req);
        if (r != IT2N_LINK_DEFER)
            it2n_link_complete(&l->pl, seq, r, NULL);
        pump_events(l);
        pump_rsp(l);
    }
}

/* HELLO: a common version, the peer's limits, ACK, our HELLO. */
static int on_hello(struct link *l, uint16_t seq, const it2n_msg_hello *h)
{
    if (h->version_max < IT2N_PROTO_VERSION_MIN || h->version_min > IT2N_PROTO_VERSION_MAX) {
        it2n_errinfo e = detail(IT2N_PROTO_ERR_VERSION, h->version_max, IT2N_PROTO_VERSION_MIN, IT2N_PROTO_VERSION_MAX);
        log_warn("link %s: peer '%.16s' speaks protocol versions %u..%u, this daemon %u..%u: refused", l->cfg.name,
                 h->node, h->version_min, h->version_max, IT2N_PROTO_VERSION_MIN, IT2N_PROTO_VERSION_MAX);
        return refuse(l, seq, IT2N_PROTO_ERR_VERSION, &e);
    }
    unsigned cap = send_window_cap(l);
    it2n_link_set_peer(&l->pl, h->window < cap ? h->window : (uint8_t)cap, h->max_payload);
    log_info("link %s: HELLO from '%.16s' (%s %08x, window %u, max_payload %u): we send up to %u "
             "frames in flight, accept %u",
             l->cfg.name, h->node, l->pl.rx_ver == IT2N_PROTO_VERSION_12 ? "v1.2, new session" : "v1.1, session",
             (unsigned)it2n_link_session(&l->pl), h->window, h->max_payload, (unsigned)it2n_link_send_window(&l->pl),
             (unsigned)it2n_link_window(&l->pl));
    l->peer = 1;
    l->hello_session = it2n_link_session(&l->pl);
    it2n_link_complete(&l->pl, seq, 0, NULL);
    send_hello(l);
    return IT2N_LINK_DEFER;
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *msg)
{
    struct link *l = app;
    struct model *md = NULL;
    it2n_errinfo err;
    int rc;
    memset(&err, 0, sizeof err);
    if (l->pl.stats.rx_sessions != l->held_sessions) {
        /* A new peer session: the link forgot the old one's deliveries, so
         * their held ACKs can no longer be sent (the restarted peer resends
         * what it needs, exactly once: protocol.md 4.3), nor the requests
         * waiting for a response run (their numbers may be the new
         * sequence's). */
        if (l->nheld || l->nrq)
            log_info("link %s: new peer session: %d ACK(s) and %d request(s) of the previous one dropped", l->cfg.name,
                     l->nheld, l->nrq);
        l->nheld = 0;
        l->nrq = 0;
        l->held_sessions = l->pl.stats.rx_sessions;
        if (l->pl.rx_ver == IT2N_PROTO_VERSION_12) {
            /* v1.2: a session is one life of the peer; what we owed the
             * previous one (responses, EVENTs, a LOST count) is not this
             * one's. (v1.1 sends responses on to the new session.) */
            l->job.kind = 0;
            l->has_rsp = 0;
            l->nev = 0;
        }
        if (l->peer && l->hello_session != it2n_link_session(&l->pl) && msg->type != IT2N_MSG_HELLO)
            l->peer = 0; /* EVENTs only to a session that said HELLO */
    }
    if (l->lost && l->lost_session != it2n_link_session(&l->pl)) {
        /* The session whose frames were dropped is gone: nobody to tell. */
        log_info("link %s: %u frame(s) dropped for a previous peer session: no EVENT LOST to the new one", l->cfg.name,
                 (unsigned)l->lost);
        l->lost = 0;
    }
    if (l->lost && l->peer && l->hello_session == l->lost_session && l->nev < EVQ_MAX) {
        /* The peer is back after we declared the link down: tell it. */
        it2n_msg_event *ev = &l->evq[l->nev++];
        memset(ev, 0, sizeof *ev);
        ev->model = IT2N_MODEL_ALL;
        ev->kind = IT2N_EV_LOST;
        ev->code = IT2N_PROTO_ERR_DOWN;
        ev->generation = l->lost;
        l->lost = 0;
    }
    switch (msg->type) {
    case IT2N_MSG_HELLO: return on_hello(l, seq, &msg->u.hello);
    case IT2N_MSG_CONFIGURE:
        log_info("link %s: CONFIGURE model %u: %s%ux%u, flags %u", l->cfg.name, msg->u.configure.model,
                 msg->u.configure.kind == IT2N_CFG_BSPLINE ? "bspline " : "", msg->u.configure.n, msg->u.configure.m,
                 msg->u.configure.flags);
        md = models_by_id(msg->u.configure.model);
        if (!md)
            return refuse_model(l, seq, msg->u.configure.model);
        if ((msg->u.configure.kind == IT2N_CFG_BSPLINE) != (md->kind == MODEL_BSPLINE)) {
            /* The kind is the configuration's ([model:ID] kind): a 4-byte
             * (Bezier) CONFIGURE of an older peer never turns a B-spline
             * model into a Bezier one, nor the reverse (protocol.md 5.3). */
            it2n_errinfo e =
                detail(IT2N_ERR_INVAL, msg->u.configure.kind, md->kind == MODEL_BSPLINE, md->kind == MODEL_BSPLINE);
            return refuse(l, seq, IT2N_ERR_INVAL, &e);
        }
        rc = models_configure(md, msg->u.configure.n, msg->u.configure.m, msg->u.configure.flags, &err);
        if (rc)
            return refuse(l, seq, rc, &err);
        hold(l, seq, store_batch());
        return IT2N_LINK_DEFER;
    case IT2N_MSG_PUT:
        log_info("link %s: PUT model %u: %u point(s) from (i=%u,j=%u,%s)%s%s", l->cfg.name, msg->u.put.model,
                 msg->u.put.count, msg->u.put.count ? msg->u.put.e[0].i : 0u, msg->u.put.count ? msg->u.put.e[0].j : 0u,
                 msg->u.put.count && it2n_fp_name(msg->u.put.e[0].fp) ? it2n_fp_name(msg->u.put.e[0].fp) : "-",
                 (msg->u.put.flags & IT2N_PUT_REPLACE) ? ", replace" : "",
                 (msg->u.put.flags & IT2N_PUT_FINE) ? ", Q30 memberships" : "");
        md = models_by_id(msg->u.put.model);
        if (!md)
            return refuse_model(l, seq, msg->u.put.model);
        return do_put(l, seq, md, &msg->u.put);
    case IT2N_MSG_COMMIT:
        log_info("link %s: COMMIT model %u", l->cfg.name, msg->u.model.model);
        md = models_by_id(msg->u.model.model);
        if (!md)
            return refuse_model(l, seq, msg->u.model.model);
        rc = models_commit(md, &err);
        if (rc) {
            if (rc == IT2N_ERR_MISSING)
                err.ch = -1;
            return refuse(l, seq, rc, &err);
        }
        hold(l, seq, store_batch());
        return IT2N_LINK_DEFER;
    case IT2N_MSG_RESET:
        for (int k = 0; k < models_count(); k++) {
            struct model *m = models_at(k);
            if (msg->u.model.model == IT2N_MODEL_ALL || m->id == msg->u.model.model) {
                if ((rc = models_clear(m)) != 0)
                    return rc;
                md = m;
            }
        }
        if (!md)
            return refuse_model(l, seq, msg->u.model.model);
        hold(l, seq, store_batch());
        return IT2N_LINK_DEFER;
    case IT2N_MSG_GET_STATUS:
    case IT2N_MSG_QUERY:
    case IT2N_MSG_LOCATE:
    case IT2N_MSG_SAMPLE:
    case IT2N_MSG_GET_NET:
        if (l->job.kind || l->has_rsp || l->nrq) {
            /* After the response in progress: unanswered until then, so
             * the peer's window bounds the queue (never BUSY). */
            if (l->nrq == (int)(sizeof l->rq / sizeof l->rq[0]))
                return IT2N_PROTO_ERR_BUSY; /* cannot happen: the link
                                               refuses a frame over the
                                               window (BUSY) first */
            l->rq[l->nrq].seq = seq;
            l->rq[l->nrq].req = *msg;
            l->nrq++;
            return IT2N_LINK_DEFER;
        }
        rc = serve(l, seq, msg);
        pump_job(l);
        return rc;
    default: return IT2N_PROTO_ERR_TYPE;
    }
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack)
{
    struct link *l = app;
    (void)nack;
    if (code)
        log_debug("link %s: our %s (seq %u) not acknowledged: %s", l->cfg.name, it2n_msg_name(type), seq,
                  it2n_proto_strerror(code));
    pump_job(l); /* a window slot may have freed */
}

static void feed(struct link *l, const uint8_t *buf, size_t n)
{
    l->backoff_ms = 500;
    flush_begin(l);
    it2n_link_input(&l->pl, buf, n, now32());
    flush_end(l);
    /* If the data needed no commit the ACKs are already out. */
    arm_poll(l);
}

static void on_serial(void *arg, int fd, short revents)
{
    struct link *l = arg;
    uint8_t buf[4096];
    ssize_t n;
    if (revents & POLLOUT) {
        if (out_flush(l) < 0) {
            link_down(l, strerror(errno));
            return;
        }
        pump_job(l); /* queue room may have freed */
        if (!(revents & (POLLIN | POLLHUP | POLLERR)))
            return;
    }
    n = read(fd, buf, sizeof buf);
    if (n > 0) {
        feed(l, buf, (size_t)n);
        return;
    }
    if (n < 0 && (errno == EAGAIN || errno == EINTR))
        return;
    if (n == 0 && l->tty && !(revents & (POLLHUP | POLLERR)))
        return; /* a tty read with VMIN 0 finds nothing: not a hang-up */
    link_down(l, n == 0 ? "hang-up" : (revents & POLLHUP) ? "hang-up" : strerror(errno));
}

static void usb_rx(void *arg, const uint8_t *buf, size_t n)
{
    feed(arg, buf, n);
}

static void usb_gone(void *arg, const char *why)
{
    link_down(arg, why);
}

/* Retransmissions of our own frames (HELLO, responses). */
static void on_poll(void *arg)
{
    struct link *l = arg;
    uint32_t now = now32();
    l->poll_timer = 0; /* this one has fired */
    if (l->fd >= 0 && l->up) {
        /* Read what has arrived first: on a loaded machine the answer to
         * a frame due for retransmission may have come in since poll()
         * returned; resending that frame would be spurious. Bounded: at
         * most 4 reads of up to 4 KiB. */
        uint8_t buf[4096];
        for (int k = 0; k < 4 && l->fd >= 0; k++) {
            ssize_t n = read(l->fd, buf, sizeof buf);
            if (n <= 0)
                break; /* EAGAIN, or a hang-up on_serial reports */
            feed(l, buf, (size_t)n);
        }
        now = now32();
        if (!l->up)
            return;
    }
    it2n_link_poll(&l->pl, now);
    if (l->cfg.peer_timeout_ms > 0 && it2n_link_stalled_ms(&l->pl, now) > (uint32_t)l->cfg.peer_timeout_ms) {
        /* The peer has not answered for peer_timeout_ms: declared down.
         * What we could not deliver is dropped and counted; the peer is
         * told (EVENT LOST) when it speaks again. */
        unsigned n = it2n_link_drop_tx(&l->pl);
        unsigned more = (unsigned)l->nev + (l->has_rsp ? 1u : 0u) + (l->job.kind ? 1u : 0u);
        if (l->lost && l->lost_session != it2n_link_session(&l->pl))
            l->lost = 0;
        l->lost_session = it2n_link_session(&l->pl);
        l->lost += n + more;
        l->nev = 0;
        l->has_rsp = 0;
        l->job.kind = 0;
        l->nrq = 0; /* unanswered requests: the peer resends them */
        log_warn("link %s: peer silent for %d ms: declared down, %u frame(s) dropped (EVENT LOST follows "
                 "when it speaks again)",
                 l->cfg.name, l->cfg.peer_timeout_ms, n + more);
    }
    pump_job(l); /* next: when a retransmission is due, else 100 ms (arm_poll) */
}

/* A fresh v1.2 session id for a peer's HELLO (protocol.md 4.1): random, so
 * that no id repeats across links or daemon restarts (the link draws again
 * if it equals one in use on this link). */
static uint32_t links_new_session(void *app)
{
    static uint32_t fallback; /* only without getrandom() */
    uint32_t v = 0;
    (void)app;
    if (getrandom(&v, sizeof v, GRND_NONBLOCK) != (ssize_t)sizeof v)
        v = ((uint32_t)loop_now_ms() ^ ((uint32_t)getpid() << 16)) + 2654435761u * ++fallback;
    return v;
}

static void link_open(void *arg)
{
    struct link *l = arg;
    it2n_link_cfg cfg;
    l->retry_timer = 0;
    if (l->cfg.type == CONF_LINK_SERIAL) {
        l->fd = link_serial_open(l->cfg.device, l->cfg.baud);
        if (l->fd < 0) {
            link_down(l, errno == EBUSY ? LINK_SERIAL_LOCKED : strerror(errno));
            return;
        }
        l->tty = isatty(l->fd);
    } else {
        l->usb = link_usb_open(&l->cfg, usb_rx, usb_gone, l);
        if (!l->usb) {
            link_down(l, "USB device not present");
            return;
        }
    }
    memset(&cfg, 0, sizeof cfg);
    l->os.write = os_write;
    l->os.state = l;
    cfg.out = &l->os;
    cfg.on_rx = on_rx;
    cfg.on_done = on_done;
    cfg.app = l;
    cfg.rto_ms = links_rto_ms(&l->cfg);
    cfg.rto_max_ms = 8 * cfg.rto_ms;
    /* serial: the RTO counts from when a frame has left the line */
    cfg.baud = l->cfg.type == CONF_LINK_SERIAL && l->cfg.baud > 0 ? (uint32_t)l->cfg.baud : 0u;
    cfg.max_tries = 0;                   /* never abandoned: retried until declared down */
    cfg.new_session = links_new_session; /* v1.2 peers get their session id */
    /* A new session id and first sequence number on every open, so that
     * a peer never takes our frames for a previous session's. */
    {
        uint32_t rnd[2] = {0, 0};
        if (getrandom(rnd, sizeof rnd, GRND_NONBLOCK) != (ssize_t)sizeof rnd) {
            rnd[0] = (uint32_t)loop_now_ms() ^ ((uint32_t)getpid() << 16);
            rnd[1] = rnd[0] * 2654435761u;
        }
        cfg.session = rnd[0] ? rnd[0] : 1u; /* 0 means "no id" */
        cfg.first_seq = (uint16_t)rnd[1];
    }
    it2n_link_init(&l->pl, &cfg);
    l->rto_ms = cfg.rto_ms;
    l->up = 1;
    l->nstage = 0;
    l->stage_bad = 0;
    l->out_off = l->out_len = 0;
    l->pollout = 0;
    l->nheld = 0;
    l->held_sessions = 0;
    l->job.kind = 0;
    l->has_rsp = 0;
    l->nrq = 0;
    l->peer = 0;
    l->nev = 0;
    if (l->fd >= 0)
        loop_add_fd(l->fd, POLLIN, on_serial, l);
    l->poll_due = now32() + 100;
    l->poll_timer = loop_add_timer(100, on_poll, l);
    log_notice("link %s: open (%s)", l->cfg.name, l->cfg.type == CONF_LINK_SERIAL ? l->cfg.device : "usb");
}

/* The first retransmission timeout of a link: rto_ms, or derived from the
 * baud rate (it2n_link_rto_default: 20 ms + one maximum frame's time,
 * counted from when the frame has left the line, which the link estimates
 * from the baud rate); 100 ms on USB. */
uint32_t links_rto_ms(const struct conf_link *c)
{
    if (c->rto_ms > 0)
        return (uint32_t)c->rto_ms;
    if (c->type == CONF_LINK_USB || c->baud <= 0)
        return 100;
    return it2n_link_rto_default((uint32_t)c->baud);
}

/* Hotplug arrival: retry waiting USB links now instead of after backoff. */
static void usb_arrived(void *arg)
{
    (void)arg;
    for (int k = 0; k < nlinks; k++) {
        struct link *l = &links[k];
        if (l->cfg.type == CONF_LINK_USB && !l->up && l->retry_timer) {
            loop_cancel_timer(l->retry_timer);
            l->retry_timer = loop_add_timer(0, link_open, l);
        }
    }
}

int links_start(const struct conf *c)
{
    backoff_max_ms = c->link_backoff_max * 1000;
    links = calloc(CONF_MAX_LINKS, sizeof *links);
    nlinks = 0;
    if (!links)
        return -1;
    if (c->nlinks && link_usb_init())
        log_warn("libusb unavailable: USB links will not open");
    link_usb_on_arrival(usb_arrived, NULL);
    for (int k = 0; k < c->nlinks; k++) {
        struct link *l = &links[nlinks++];
        l->cfg = c->link[k];
        l->fd = -1;
        l->backoff_ms = 500;
        link_open(l);
    }
    return 0;
}

int links_reload(const struct conf *c)
{
    int same = c->nlinks == nlinks;
    backoff_max_ms = c->link_backoff_max * 1000;
    for (int k = 0; same && k < nlinks; k++)
        same = conf_link_same(&c->link[k], &links[k].cfg);
    if (same)
        return 0;
    /* Simple and safe: reopen all (unacknowledged frames are retransmitted
     * by the instruments). */
    log_notice("links changed; reopening");
    links_stop();
    return links_start(c);
}

void links_release(int commit_ok)
{
    links_release_upto(UINT64_MAX, commit_ok);
}

void links_release_upto(uint64_t batch, int commit_ok)
{
    for (int k = 0; k < nlinks; k++) {
        struct link *l = &links[k];
        int keep = 0;
        flush_begin(l);
        for (int h = 0; h < l->nheld; h++) {
            if (l->held_batch[h] > batch) {
                l->held_batch[keep] = l->held_batch[h];
                l->held[keep++] = l->held[h];
                continue;
            }
            it2n_link_complete(&l->pl, l->held[h], commit_ok ? 0 : IT2ND_ERR_IO, NULL);
        }
        l->nheld = keep;
        if (l->up)
            pump_job(l); /* EVENTs of this commit go out after its ACKs */
        flush_end(l);
    }
}

void links_stop(void)
{
    for (int k = 0; k < nlinks; k++) {
        struct link *l = &links[k];
        if (l->retry_timer)
            loop_cancel_timer(l->retry_timer);
        if (l->poll_timer)
            loop_cancel_timer(l->poll_timer);
        if (l->fd >= 0) {
            loop_del_fd(l->fd);
            close(l->fd);
        }
        if (l->usb)
            link_usb_close(l->usb);
    }
    free(links);
    links = NULL;
    nlinks = 0;
    link_usb_free();
}

void links_event(const struct model *md, int old_state)
{
    it2n_msg_event ev;
    memset(&ev, 0, sizeof ev);
    ev.model = (uint8_t)md->id;
    ev.generation = md->gen;
    if (md->state == IT2N_REGMAP_STATE_FAILED) {
        ev.kind = IT2N_EV_ERROR;
        ev.code = (int16_t)md->last_err.code;
    } else if (md->last_op == MOP_CONFIG && md->state == IT2N_REGMAP_STATE_EMPTY) {
        ev.kind = IT2N_EV_CONFIGURED;
    } else if (md->last_op == MOP_CLEAR && md->state == IT2N_REGMAP_STATE_EMPTY) {
        ev.kind = IT2N_EV_RESET;
    } else if (md->state == IT2N_REGMAP_STATE_SOLVED &&
               (old_state != IT2N_REGMAP_STATE_SOLVED || md->last_op == MOP_COMMIT)) {
        ev.kind = IT2N_EV_SOLVED;
    } else {
        ev.kind = IT2N_EV_UPDATED;
    }
    for (int k = 0; k < nlinks; k++) {
        struct link *l = &links[k];
        int q;
        if (!l->up || !l->peer || it2n_link_session(&l->pl) != l->hello_session)
            continue; /* EVENTs only to a peer session that said HELLO */
        /* Coalesce: a queued EVENT of this model is replaced in place. */
        for (q = 0; q < l->nev && l->evq[q].model != ev.model; q++) {
        }
        if (q < l->nev) {
            l->evq[q] = ev;
            l->ev_merged++;
        } else if (l->nev < EVQ_MAX) {
            l->evq[l->nev++] = ev;
        } else {
            log_warn("link %s: EVENT queue full; model %u event dropped", l->cfg.name, ev.model);
            continue;
        }
        if (!l->nheld) {
            pump_events(l); /* else after the ACKs (links_release_upto) */
            arm_poll(l);
        }
    }
}

int links_out_stats(int k, struct links_out_stats *st)
{
    if (k < 0 || k >= nlinks)
        return -1;
    *st = links[k].st;
    return 0;
}

int links_up(void)
{
    int up = 0;
    for (int k = 0; k < nlinks; k++)
        up += links[k].up;
    return up;
}
