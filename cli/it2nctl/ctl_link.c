/*
 * it2nctl over a serial line or pty with the it2n framing protocol
 * (docs/protocol.md), through the public protocol/ API as the example
 * instrument uses it (examples/instrument/session.c): it2n_link for the
 * reliable transport, it2n_msg structs for the messages. One request at a
 * time: send, wait for its ACK (or NACK) and for its response frames.
 * Values are exact (Q24 on the wire); parameters travel as Q2.30.
 */
#include "ctl.h"

#include "it2n_link.h"

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

typedef struct lk_conn {
    it2n_link link;
    it2n_ostream os;
    it2n_istream is;
    int fd;
    int io_err; /* errno of a failed read/write, or -1 EOF */
    uint8_t model;
    unsigned timeout_ms;
    char where[300];
    /* the request in flight */
    int32_t req_seq; /* -1: none                             */
    int req_done;    /* 0 waiting, 1 ACKed, < 0 NACK/timeout */
    it2n_msg_nack nack;
    bool have_rsp;
    it2n_msg rsp; /* STATUS, QUERY_RESULT, LOCATE_RESULT  */
    /* multi-frame answers */
    ctl_net *net;
    unsigned net_fp, net_rows;
    it2n_val (*samp)[IT2N_CH_COUNT];
    uint32_t samp_total, samp_got;
    /* the daemon's HELLO: v1.3 (IT2N_CAP_BSPLINE, IT2N_CAP_FINE) or older */
    bool peer_hello;
    uint32_t peer_caps;
    /* EVENTs of our model */
    bool event;
    uint32_t event_gen;
    /* it2n_frame_write hands a frame over in COBS blocks: they are
     * collected and the frame goes out in one write (one wake-up of the
     * daemon per frame, not one per block) */
    uint8_t stage[IT2N_FRAME_MAX_WIRE];
    size_t nstage;
} lk_conn;

static uint32_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u);
}

static int fd_write_all(lk_conn *c, const uint8_t *buf, size_t len)
{
    while (len > 0) {
        ssize_t n = write(c->fd, buf, len);
        if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
            struct pollfd p = {c->fd, POLLOUT, 0};
            if (poll(&p, 1, 1000) <= 0) {
                return -1; /* not draining: the frame is retransmitted */
            }
            continue;
        }
        if (n <= 0) {
            c->io_err = n < 0 ? errno : -1;
            return -1;
        }
        buf += n;
        len -= (size_t)n;
    }
    return 0;
}

static int fd_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    lk_conn *c = s->state;
    int r;
    if (len > sizeof c->stage - c->nstage) { /* never for a valid frame */
        r = fd_write_all(c, c->stage, c->nstage);
        c->nstage = 0;
        return r != 0 ? r : fd_write_all(c, buf, len);
    }
    memcpy(c->stage + c->nstage, buf, len);
    c->nstage += len;
    if (len == 0 || buf[len - 1] != 0)
        return 0; /* more blocks of this frame follow */
    r = fd_write_all(c, c->stage, c->nstage);
    c->nstage = 0;
    return r;
}

static int fd_read(it2n_istream *s, uint8_t *buf, size_t len)
{
    lk_conn *c = s->state;
    ssize_t n = read(c->fd, buf, len);
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
        return 0;
    }
    if (n <= 0) {
        c->io_err = n < 0 ? errno : -1;
        return -1;
    }
    return (int)n;
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *msg)
{
    lk_conn *c = app;
    (void)seq;
    switch (msg->type) {
    case IT2N_MSG_EVENT:
        if (msg->u.event.model == c->model) {
            c->event = true;
            c->event_gen = msg->u.event.generation;
        }
        break;
    case IT2N_MSG_STATUS:
    case IT2N_MSG_QUERY_RESULT:
    case IT2N_MSG_LOCATE_RESULT:
        /* re is the first field of every response */
        if (c->req_seq >= 0 && msg->u.status.re == (uint16_t)c->req_seq) {
            c->rsp = *msg;
            c->have_rsp = true;
        }
        break;
    case IT2N_MSG_NET_ROW: {
        const it2n_msg_net_row *r = &msg->u.net_row;
        if (c->net != NULL && c->req_seq >= 0 && r->re == (uint16_t)c->req_seq && r->fp == c->net_fp &&
            r->row < IT2N_DIM && r->m < IT2N_DIM) {
            memcpy((*c->net)[r->fp][r->row], r->v, (r->m + 1u) * sizeof(r->v[0]));
            c->net_rows++;
        }
        break;
    }
    case IT2N_MSG_SAMPLE_DATA: {
        const it2n_msg_sample_data *d = &msg->u.sample_data;
        if (c->samp != NULL && c->req_seq >= 0 && d->re == (uint16_t)c->req_seq &&
            d->start + d->count <= c->samp_total) {
            memcpy(c->samp[d->start], d->v, d->count * sizeof(d->v[0]));
            c->samp_got += d->count;
        }
        break;
    }
    case IT2N_MSG_HELLO:
        /* The daemon's limits bind what we send (protocol.md, HELLO). */
        it2n_link_set_peer(&c->link, msg->u.hello.window, msg->u.hello.max_payload);
        c->peer_hello = true;
        c->peer_caps = msg->u.hello.caps;
        break;
    default: break; /* anything else: ACK */
    }
    return 0;
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack)
{
    lk_conn *c = app;
    (void)type;
    if (c->req_seq >= 0 && seq == (uint16_t)c->req_seq) {
        c->req_done = code == 0 ? 1 : code;
        if (nack != NULL) {
            c->nack = *nack;
        } else {
            memset(&c->nack, 0, sizeof(c->nack));
            c->nack.code = (int16_t)code;
        }
    }
}

/* Run the link until done(c) or timeout_ms pass without progress. */
static int run_until(lk_conn *c, bool (*done)(const lk_conn *), unsigned timeout_ms)
{
    uint32_t start = now_ms();
    uint32_t progress = c->samp_got + c->net_rows;
    while (!done(c)) {
        uint32_t now = now_ms(), wait = it2n_link_next_timeout(&c->link, now);
        struct pollfd p = {c->fd, POLLIN, 0};
        if (c->samp_got + c->net_rows != progress) {
            progress = c->samp_got + c->net_rows;
            start = now;
        }
        if (now - start >= timeout_ms) {
            return -1;
        }
        if (wait > timeout_ms - (now - start)) {
            wait = timeout_ms - (now - start);
        }
        if (wait > 50u) {
            wait = 50u;
        }
        if (poll(&p, 1, (int)wait) < 0 && errno != EINTR) {
            c->io_err = errno;
            return -2;
        }
        if (it2n_link_pump(&c->link, now_ms()) < 0) {
            return -2;
        }
        (void)it2n_link_poll(&c->link, now_ms());
    }
    return 0;
}

static bool acked(const lk_conn *c)
{
    return c->req_done != 0;
}

static bool answered(const lk_conn *c)
{
    if (c->req_done < 0) {
        return true;
    }
    if (c->req_done == 0) {
        return false;
    }
    if (c->samp != NULL) {
        return c->samp_got >= c->samp_total;
    }
    if (c->net != NULL) {
        return c->net_rows >= c->samp_total;
    }
    return c->have_rsp;
}

static bool can_send(const lk_conn *c)
{
    return it2n_link_can_send(&c->link);
}

static int comm_fail(lk_conn *c, int how, const char *what)
{
    if (how == -2) {
        fprintf(stderr, "it2nctl: %s: %s: %s\n", c->where, what, c->io_err > 0 ? strerror(c->io_err) : "hang-up");
    } else {
        fprintf(stderr,
                "it2nctl: %s: %s: no answer from it2nd within %u ms "
                "(is a [link:] of the daemon on the other end?)\n",
                c->where, what, c->timeout_ms);
    }
    return CTL_EXIT_COMM;
}

/* Send msg and wait for its ACK and, with wait_rsp, its response(s).
 * Returns CTL_EXIT_OK, CTL_REJECTED (c->nack holds the refusal) or a
 * printed failure. */
static int request(lk_conn *c, it2n_msg *msg, bool wait_rsp, const char *what)
{
    /* Sent once: the link retransmits until ACKed, and a v1.1 daemon
     * retries its response frames until it declares the link down
     * (protocol.md section 4), so a request is never sent again here
     * (that would be a second request, answered after the first). */
    int32_t seq;
    int rc = run_until(c, can_send, c->timeout_ms);
    if (rc != 0) {
        return comm_fail(c, rc, what);
    }
    c->req_done = 0;
    c->have_rsp = false;
    c->samp_got = 0;
    c->net_rows = 0;
    c->req_seq = -1;
    seq = it2n_link_send(&c->link, msg, now_ms());
    if (seq < 0) {
        fprintf(stderr, "it2nctl: %s: %s: cannot send: %s\n", c->where, what, it2n_proto_strerror((int)seq));
        return CTL_EXIT_COMM;
    }
    c->req_seq = seq;
    rc = run_until(c, wait_rsp ? answered : acked, c->timeout_ms);
    c->req_seq = -1;
    if (rc == -2) {
        return comm_fail(c, rc, what);
    }
    if (rc == -1 || c->req_done == IT2N_PROTO_ERR_TIMEOUT) {
        return comm_fail(c, -1, what);
    }
    if (c->req_done < 0) {
        return CTL_REJECTED;
    }
    return CTL_EXIT_OK;
}

static const char *code_text(int code)
{
    return code <= -100 ? it2n_proto_strerror(code) : it2n_strerror(code);
}

/* A refusal of a non-data request: print it. */
static int refused(const lk_conn *c, const char *what)
{
    fprintf(stderr, "it2nctl: %s: %s refused by it2nd: %s (%d)%s\n", c->where, what, code_text(c->nack.code),
            c->nack.code,
            c->nack.code == IT2N_ERR_STATE         ? ": the model is not solved"
            : c->nack.code == IT2N_PROTO_ERR_MODEL ? ": no such model on the daemon (--model ID)"
                                                   : "");
    return CTL_EXIT_DATA;
}

/* A query (status, eval, locate, net, sample): request with its
 * response(s), a refusal printed. CTL_EXIT_OK or an exit status. */
static int query(lk_conn *c, it2n_msg *msg, const char *what)
{
    int rc = request(c, msg, true, what);
    return rc == CTL_REJECTED ? refused(c, what) : rc;
}

static int lk_status(void *p, ctl_status *st)
{
    lk_conn *c = p;
    it2n_msg m;
    const it2n_msg_status *s;
    int rc;
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_GET_STATUS;
    m.u.model.model = c->model;
    rc = query(c, &m, "status");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    s = &c->rsp.u.status;
    memset(st, 0, sizeof(*st));
    st->model = s->model;
    st->state = s->state;
    st->n = s->n;
    st->m = s->m;
    st->flags = s->flags;
    st->required = s->n == 0u ? 0u : (s->n + 1u) * (s->m + 1u) * ((s->flags & IT2N_F_TYPE1) ? 1u : IT2N_FP_COUNT);
    st->present = st->required > s->missing ? st->required - s->missing : 0u;
    st->generation = s->generation;
    st->last_error = s->last_error;
    /* STATUS has no kind (protocol v1.x): sizes beyond the Bezier degrees
     * can only be a B-spline model, whose nets the link does not carry */
    st->kind = s->n > IT2N_MAX_DEGREE || s->m > IT2N_MAX_DEGREE ? 1u : 0u;
    st->net_rows = st->state == CTL_ST_SOLVED && !st->kind ? s->n + 1u : 0u;
    st->net_cols = st->state == CTL_ST_SOLVED && !st->kind ? s->m + 1u : 0u;
    return CTL_EXIT_OK;
}

static void nack_info(const lk_conn *c, it2n_errinfo *rej)
{
    memset(rej, 0, sizeof(*rej));
    rej->code = c->nack.code;
    rej->i = c->nack.i;
    rej->j = c->nack.j;
    rej->fp = c->nack.fp;
    rej->ch = c->nack.ch;
    rej->value = c->nack.value;
    rej->lo = c->nack.lo;
    rej->hi = c->nack.hi;
}

/* Entry (i, j, fp) as a PUT carries it: memberships in Q30 (fine) or
 * Q24 (exact: push_format checked). */
static void src_get_wire(const cli_data *s, unsigned i, unsigned j, unsigned fp, bool fine, it2n_val v[IT2N_CH_COUNT])
{
    cli_data_get_fine(s, i, j, fp, v);
    for (unsigned ch = IT2N_CH_T; !fine && ch <= IT2N_CH_F; ch++) {
        v[ch] /= (it2n_val)1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC);
    }
}

/* A membership finer than Q24 in the source: what a PUT without FINE
 * would round (its (i, j, fp) in *at), or false. */
static bool src_finer_than_q24(const cli_data *s, unsigned at[3])
{
    const it2n_val low = ((it2n_val)1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC)) - 1;
    for (unsigned i = 0; i <= s->n; i++) {
        for (unsigned j = 0; j <= s->m; j++) {
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                if (!cli_data_has(s, i, j, fp)) {
                    continue;
                }
                cli_data_get_fine(s, i, j, fp, v);
                if ((v[IT2N_CH_T] & low) || (v[IT2N_CH_I] & low) || (v[IT2N_CH_F] & low)) {
                    at[0] = i;
                    at[1] = j;
                    at[2] = fp;
                    return true;
                }
            }
        }
    }
    return false;
}

static bool hello_seen(const lk_conn *c)
{
    return c->peer_hello;
}

/* What the daemon's HELLO (sent right after it ACKed ours) allows for
 * src: CTL_EXIT_OK with *fine set when memberships may travel in Q30 (PUT
 * FINE), or CTL_EXIT_DATA with the reason printed, nothing sent. */
static int push_format(lk_conn *c, const cli_data *src, bool *fine)
{
    unsigned at[3];
    *fine = false;
    if (src->bds != NULL) {
        /* v1.3: a v1.2 daemon would refuse the B-spline CONFIGURE as
         * malformed */
        if (run_until(c, hello_seen, c->timeout_ms) != 0 || !(c->peer_caps & IT2N_CAP_BSPLINE)) {
            fprintf(stderr,
                    "it2nctl: %s: push --kind bspline: %s (protocol v1.3, "
                    "docs/protocol.md 5.3); push over Modbus (--tcp or --rtu) "
                    "or upgrade it2nd (nothing was sent)\n",
                    c->where,
                    c->peer_hello ? "this it2nd's link speaks protocol v1.2, without the B-spline CONFIGURE"
                                  : "it2nd did not say which protocol revision it speaks");
            return CTL_EXIT_DATA;
        }
    }
    /* v1.3: memberships travel in Q30 (PUT FINE) when the daemon reads
     * them, so it holds what 'it2n' reads from the same CSV. A daemon
     * without FINE gets Q24 only when that is exact; otherwise rounding
     * would give it another model: refused, nothing sent. */
    if (run_until(c, hello_seen, c->timeout_ms) == 0 && (c->peer_caps & IT2N_CAP_FINE)) {
        *fine = true;
    } else if (src_finer_than_q24(src, at)) {
        fprintf(stderr,
                "it2nctl: %s: push: the membership of (i=%u, j=%u, %s) is finer than 2^-24 and %s "
                "(PUT FINE, protocol v1.3, docs/protocol.md 5.4); rounding would give it another model "
                "than 'it2n': push over Modbus (--tcp or --rtu) or upgrade it2nd (nothing was sent)\n",
                c->where, at[0], at[1], it2n_fp_name(at[2]) ? it2n_fp_name(at[2]) : "?",
                c->peer_hello ? "this it2nd's link carries memberships in Q24 only"
                              : "it2nd did not say whether its link carries Q30 memberships");
        return CTL_EXIT_DATA;
    }
    return CTL_EXIT_OK;
}

/* CONFIGURE (the 5-byte v1.3 form for a B-spline), every entry in PUTs of
 * as many as fit (FINE when the daemon reads it), COMMIT. */
static int lk_push(void *p, const cli_data *src, ctl_progress_fn progress, void *pctx, it2n_errinfo *rej)
{
    static it2n_msg m;
    lk_conn *c = p;
    unsigned i, j, fp, total = cli_data_count(src), done = 0;
    bool fine;
    int rc = push_format(c, src, &fine);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.model = c->model;
    m.u.configure.n = (uint8_t)src->n;
    m.u.configure.m = (uint8_t)src->m;
    m.u.configure.flags = (uint8_t)src->flags;
    m.u.configure.kind = src->bds != NULL ? IT2N_CFG_BSPLINE : IT2N_CFG_BEZIER;
    rc = request(c, &m, false, "configure");
    if (rc == CTL_REJECTED) {
        if (c->nack.code == IT2N_ERR_INVAL && c->nack.value == m.u.configure.kind && c->nack.lo == c->nack.hi &&
            c->nack.lo != c->nack.value) {
            /* the model's configured kind is the other one (5.3) */
            return ctl_wrong_kind(c->where, c->nack.lo != 0, src, "changed");
        }
        if (c->nack.code == IT2N_ERR_RANGE && c->nack.i < 0) {
            fprintf(stderr,
                    "it2nctl: %s: configure refused by it2nd: %lld intervals, its model holds "
                    "at most %lld (n, m of its [model:] section; nothing was changed)\n",
                    c->where, (long long)c->nack.value, (long long)c->nack.hi);
            return CTL_EXIT_DATA;
        }
        return refused(c, "configure");
    }
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_PUT;
    m.u.put.model = c->model;
    m.u.put.flags = fine ? IT2N_PUT_FINE : 0u;
    for (i = 0; i <= src->n; i++) {
        for (j = 0; j <= src->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_put_entry *e;
                if (!cli_data_has(src, i, j, fp)) {
                    continue;
                }
                e = &m.u.put.e[m.u.put.count++];
                e->i = (uint8_t)i;
                e->j = (uint8_t)j;
                e->fp = (uint8_t)fp;
                src_get_wire(src, i, j, fp, fine, e->vals);
                if (!(src->flags & IT2N_F_Z)) {
                    e->vals[IT2N_CH_Z] = 0;
                }
                if (m.u.put.count < IT2N_PUT_MAX && done + m.u.put.count < total) {
                    continue;
                }
                rc = request(c, &m, false, "upload");
                if (rc == CTL_REJECTED) {
                    nack_info(c, rej);
                    return CTL_REJECTED;
                }
                if (rc != CTL_EXIT_OK) {
                    return rc;
                }
                done += m.u.put.count;
                m.u.put.count = 0;
                if (progress != NULL) {
                    progress(pctx, done, total);
                }
            }
        }
    }
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_COMMIT;
    m.u.model.model = c->model;
    rc = request(c, &m, false, "commit");
    if (rc == CTL_REJECTED) {
        nack_info(c, rej);
        return CTL_REJECTED;
    }
    return rc;
}

static int lk_eval(void *p, it2n_par *u, it2n_par *w, it2n_point *pt)
{
    lk_conn *c = p;
    it2n_msg m;
    const it2n_msg_query_result *q;
    int rc;
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_QUERY;
    m.u.query.model = c->model;
    m.u.query.u = it2n_par_to_wire(*u);
    m.u.query.w = it2n_par_to_wire(*w);
    rc = query(c, &m, "query");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    q = &c->rsp.u.query_result;
    *u = it2n_par_from_wire(q->u);
    *w = it2n_par_from_wire(q->w);
    memcpy(pt->v, q->v, sizeof(pt->v));
    pt->sum = q->sum;
    pt->out_of_range = q->out_of_range;
    return CTL_EXIT_OK;
}

static int lk_locate(void *p, it2n_val *x, it2n_val *y, ctl_loc res[IT2N_FP_COUNT])
{
    lk_conn *c = p;
    it2n_msg m;
    unsigned fp;
    int rc;
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_LOCATE;
    m.u.locate.model = c->model;
    m.u.locate.x = *x;
    m.u.locate.y = *y;
    rc = query(c, &m, "locate");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        const it2n_locate_wire *lw = &c->rsp.u.locate_result.fp[fp];
        res[fp].has_uw = true;
        res[fp].u = it2n_par_from_wire(lw->u);
        res[fp].w = it2n_par_from_wire(lw->w);
        res[fp].status = lw->status;
        memcpy(res[fp].v, lw->v, sizeof(res[fp].v));
    }
    return CTL_EXIT_OK;
}

static int lk_net(void *p, const ctl_status *st, ctl_net *net)
{
    lk_conn *c = p;
    it2n_msg m;
    unsigned fp;
    int rc = CTL_EXIT_OK;
    memset(net, 0, sizeof(*net));
    for (fp = 0; fp < IT2N_FP_COUNT && rc == CTL_EXIT_OK; fp++) {
        if ((st->flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
            continue;
        }
        memset(&m, 0, sizeof(m));
        m.type = IT2N_MSG_GET_NET;
        m.u.get_net.model = c->model;
        m.u.get_net.fp = (uint8_t)fp;
        c->net = net;
        c->net_fp = fp;
        c->net_rows = 0;
        c->samp_total = st->n + 1u;
        rc = query(c, &m, "control net");
        c->net = NULL;
    }
    return rc;
}

static int lk_sample(void *p, const ctl_status *st, unsigned rows, unsigned cols, ctl_sample_fn cb, void *ctx)
{
    lk_conn *c = p;
    size_t nodes = (size_t)rows * cols;
    it2n_val(*all)[IT2N_CH_COUNT];
    it2n_msg m;
    unsigned fp, r, cc;
    bool type1 = (st->flags & IT2N_F_TYPE1) != 0u;
    int rc = CTL_EXIT_OK;
    if (nodes > 65536u) {
        fprintf(stderr,
                "it2nctl: %s: sample: at most 65536 nodes over a "
                "link (--grid %ux%u has %zu)\n",
                c->where, rows, cols, nodes);
        return CTL_EXIT_DATA;
    }
    all = malloc(nodes * IT2N_FP_COUNT * sizeof(*all));
    if (all == NULL) {
        fprintf(stderr, "it2nctl: out of memory for a %ux%u grid\n", rows, cols);
        return CTL_EXIT_DATA;
    }
    memset(all, 0, nodes * IT2N_FP_COUNT * sizeof(*all));
    for (fp = 0; fp < IT2N_FP_COUNT && rc == CTL_EXIT_OK; fp++) {
        if (type1 && fp != IT2N_FP_D) {
            continue;
        }
        memset(&m, 0, sizeof(m));
        m.type = IT2N_MSG_SAMPLE;
        m.u.sample.model = c->model;
        m.u.sample.fp = (uint8_t)fp;
        m.u.sample.rows = (uint16_t)rows;
        m.u.sample.cols = (uint16_t)cols;
        c->samp = &all[fp * nodes];
        c->samp_total = (uint32_t)nodes;
        c->samp_got = 0;
        rc = query(c, &m, "sample");
        c->samp = NULL;
    }
    for (r = 0; r < rows && rc == CTL_EXIT_OK; r++) {
        for (cc = 0; cc < cols && rc == CTL_EXIT_OK; cc++) {
            it2n_point pt;
            size_t k = (size_t)r * cols + cc;
            memset(&pt, 0, sizeof(pt));
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                memcpy(pt.v[fp], all[fp * nodes + k], sizeof(pt.v[fp]));
            }
            ctl_summarise(type1, &pt);
            /* The daemon's SAMPLE evaluates at floor(r * 2^32 / (rows-1))
             * (daemon/links.c); print the parameters it used. */
            rc = cb(ctx, r, cc, (it2n_par)(((uint64_t)r << IT2N_PAR_FRAC) / (rows - 1u)),
                    (it2n_par)(((uint64_t)cc << IT2N_PAR_FRAC) / (cols - 1u)), &pt);
        }
    }
    free(all);
    return rc;
}

static bool got_event(const lk_conn *c)
{
    return c->event;
}

static int lk_wait(void *p, uint32_t gen, int timeout_ms, ctl_status *st)
{
    lk_conn *c = p;
    int rc = run_until(c, got_event, (unsigned)timeout_ms);
    if (rc == -2) {
        return comm_fail(c, rc, "watch");
    }
    if (c->event && c->event_gen == gen) {
        c->event = false; /* a change that kept the generation */
    }
    c->event = false;
    return lk_status(c, st);
}

static void lk_close(void *p)
{
    lk_conn *c = p;
    /* Let the last ACKs go out before the line closes. */
    (void)it2n_link_poll(&c->link, now_ms());
    close(c->fd);
    free(c);
}

static const ctl_ops lk_ops = {"link", lk_status, lk_push, lk_eval,  lk_locate,
                               lk_net, lk_sample, lk_wait, lk_close, NULL};

static speed_t baud_const(unsigned baud)
{
    switch (baud) {
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    default: return B115200;
    }
}

void *ctl_link_open(const ctl_conn_opts *o, const ctl_ops **ops, int *rc)
{
    lk_conn *c = calloc(1, sizeof(*c));
    it2n_link_cfg cfg;
    struct termios t;
    it2n_msg m;
    int r;
    if (c == NULL) {
        fprintf(stderr, "it2nctl: out of memory\n");
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    snprintf(c->where, sizeof(c->where), "%s model %u", o->link, o->model);
    c->model = (uint8_t)o->model;
    c->timeout_ms = o->timeout_ms;
    c->req_seq = -1;
    c->fd = open(o->link, O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (c->fd < 0) {
        fprintf(stderr, "it2nctl: cannot open %s: %s\n", o->link, strerror(errno));
        free(c);
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    if (isatty(c->fd) && tcgetattr(c->fd, &t) == 0) {
        cfmakeraw(&t);
        cfsetispeed(&t, baud_const(o->baud));
        cfsetospeed(&t, baud_const(o->baud));
        t.c_cc[VMIN] = 1;
        t.c_cc[VTIME] = 0;
        tcsetattr(c->fd, TCSANOW, &t);
        tcflush(c->fd, TCIFLUSH); /* frames meant for an earlier peer */
    }
    c->os.write = fd_write;
    c->os.state = c;
    c->is.read = fd_read;
    c->is.state = c;
    memset(&cfg, 0, sizeof(cfg));
    cfg.out = &c->os;
    cfg.in = &c->is;
    cfg.on_rx = on_rx;
    cfg.on_done = on_done;
    cfg.app = c;
    /* Retransmit every 200 ms (the daemon's default RTO) until the
     * request timeout has passed. */
    cfg.rto_ms = o->timeout_ms < 200u ? o->timeout_ms : 200u;
    cfg.max_tries = (uint8_t)(o->timeout_ms / cfg.rto_ms > 255u ? 255u : o->timeout_ms / cfg.rto_ms + 1u);
    /* A fresh random session id and first sequence number each run
     * (protocol.md 4.2): a SYN frame of a new session is never taken for a
     * retransmission of an earlier one's. */
    {
        uint32_t rnd[2] = {now_ms() ^ (uint32_t)getpid(), (now_ms() ^ (uint32_t)getpid()) * 2654435761u};
        if (getrandom(rnd, sizeof rnd, GRND_NONBLOCK) != (ssize_t)sizeof rnd)
            rnd[0] ^= (uint32_t)time(NULL);
        cfg.session = rnd[0] ? rnd[0] : 1u;
        cfg.first_seq = (uint16_t)rnd[1];
    }
    if (it2n_link_init(&c->link, &cfg) != IT2N_OK) {
        close(c->fd);
        free(c);
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    memset(&m, 0, sizeof(m));
    m.type = IT2N_MSG_HELLO;
    m.u.hello.version_min = IT2N_PROTO_VERSION;
    m.u.hello.version_max = IT2N_PROTO_VERSION;
    m.u.hello.max_degree = IT2N_MAX_DEGREE;
    m.u.hello.window = it2n_link_window(&c->link);
    m.u.hello.caps = IT2N_CAP_INSTRUMENT | IT2N_CAP_Z | IT2N_CAP_TYPE1 | IT2N_CAP_CHORD;
    m.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
    m.u.hello.max_models = 0;
    memcpy(m.u.hello.node, "it2nctl", 7);
    r = request(c, &m, false, "hello");
    if (r != CTL_EXIT_OK) {
        if (r == CTL_REJECTED) {
            fprintf(stderr, "it2nctl: %s: HELLO refused: %s\n", c->where, code_text(c->nack.code));
            r = CTL_EXIT_COMM;
        }
        close(c->fd);
        free(c);
        *rc = r;
        return NULL;
    }
    *ops = &lk_ops;
    *rc = CTL_EXIT_OK;
    return c;
}
