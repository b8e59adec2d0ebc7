/* Instrument session state machine (see session.h). */
#include <string.h>

#include "session.h"

static int on_rx(void *app, uint16_t seq, const it2n_msg *msg)
{
    session *s = app;
    /* The peer's HELLO: apply its window and max_payload (PUT batches are
     * cut to fit). EVENTs need no action here; ACK them so the peer does
     * not retransmit. */
    (void)seq;
    if (msg->type == IT2N_MSG_HELLO) {
        it2n_link_set_peer(&s->link, msg->u.hello.window, msg->u.hello.max_payload);
        s->peer_caps = msg->u.hello.caps;
    }
    return 0;
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack)
{
    session *s = app;
    if (code == 0 || s->state == SESSION_FAILED)
        return;
    s->state = SESSION_FAILED;
    s->fail_code = code;
    s->fail_seq = seq;
    s->fail_type = type;
    if (nack != NULL)
        s->nack = *nack;
}

int session_init(session *s, const it2n_dataset *ds, uint8_t model, it2n_ostream *out, it2n_istream *in,
                 uint32_t rto_ms, uint8_t tries, bool oneway, uint16_t first_seq, uint32_t session_id)
{
    it2n_link_cfg cfg;
    memset(s, 0, sizeof *s);
    s->ds = ds;
    s->model = model;
    s->oneway = oneway;
    s->out = out;
    memset(&cfg, 0, sizeof cfg);
    cfg.out = out;
    cfg.in = in;
    cfg.on_rx = on_rx;
    cfg.on_done = on_done;
    cfg.app = s;
    cfg.rto_ms = rto_ms;
    cfg.max_tries = tries;
    cfg.first_seq = first_seq;
    cfg.session = session_id;
    /* v1.2: the daemon hands out the session id (its HELLO); one-way mode
     * hears no answer, so it speaks v1.1 with session_id */
    cfg.version = oneway ? (uint8_t)IT2N_PROTO_VERSION : (uint8_t)IT2N_PROTO_VERSION_12;
    s->ow_hdr.seq = first_seq;
    return it2n_link_init(&s->link, &cfg);
}

/* Fill the next PUT batch; false when the data set is exhausted. */
static bool next_put(session *s, it2n_msg *m)
{
    it2n_msg_put *p = &m->u.put;
    /* as many entries as the daemon's announced max_payload takes */
    unsigned max = (it2n_link_max_payload(&s->link) - IT2N_PUT_HDR) / IT2N_PUT_ENTRY;
    if (max > IT2N_PUT_MAX)
        max = IT2N_PUT_MAX;
    memset(m, 0, sizeof *m);
    m->type = IT2N_MSG_PUT;
    p->model = s->model;
    /* v1.3: memberships as stored (Q30) when the daemon reads PUT FINE,
     * so its model is the CSV's as 'it2n' reads it; else (a v1.2 daemon,
     * one-way mode) Q24, rounded */
    if (s->peer_caps & IT2N_CAP_FINE)
        p->flags = IT2N_PUT_FINE;
    while (s->i <= s->ds->n && p->count < max) {
        if (s->ds->present[s->i][s->j] & (1u << s->fp)) {
            it2n_put_entry *e = &p->e[p->count++];
            e->i = (uint8_t)s->i;
            e->j = (uint8_t)s->j;
            e->fp = (uint8_t)s->fp;
            if (p->flags & IT2N_PUT_FINE)
                it2n_dataset_get_fine(s->ds, s->i, s->j, s->fp, e->vals);
            else
                it2n_dataset_get(s->ds, s->i, s->j, s->fp, e->vals);
        }
        if (++s->fp == IT2N_FP_COUNT) {
            s->fp = 0;
            if (++s->j > s->ds->m) {
                s->j = 0;
                s->i++;
            }
        }
    }
    return p->count > 0;
}

/* Build the message for the current step; false when nothing is left. */
static bool build(session *s, it2n_msg *m)
{
    memset(m, 0, sizeof *m);
    switch (s->step) {
    case 0:
        m->type = IT2N_MSG_HELLO;
        /* the one version this session speaks */
        m->u.hello.version_min = s->link.cfg.version;
        m->u.hello.version_max = s->link.cfg.version;
        m->u.hello.max_degree = IT2N_MAX_DEGREE;
        m->u.hello.window = it2n_link_window(&s->link);
        m->u.hello.caps = IT2N_CAP_INSTRUMENT | IT2N_CAP_Z | IT2N_CAP_TYPE1 | IT2N_CAP_CHORD;
        m->u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
        m->u.hello.max_models = 1;
        memcpy(m->u.hello.node, "it2n-instrument", 15);
        return true;
    case 1:
        m->type = IT2N_MSG_CONFIGURE;
        m->u.configure.model = s->model;
        m->u.configure.n = s->ds->n;
        m->u.configure.m = s->ds->m;
        m->u.configure.flags = s->ds->flags;
        return true;
    case 2: return next_put(s, m);
    case 3:
        m->type = IT2N_MSG_COMMIT;
        m->u.model.model = s->model;
        return true;
    default: return false;
    }
}

/* One-way mode: frame and write without the link (nothing to answer). */
static int send_oneway(session *s, const it2n_msg *m)
{
    uint8_t payload[IT2N_FRAME_MAX_LEN];
    size_t sess = s->step == 0u ? IT2N_FRAME_SESSION_SIZE : 0u;
    int len = it2n_msg_pack(m, payload + sess, IT2N_PROTO_MAX_PAYLOAD, NULL);
    unsigned b;
    if (len < 0)
        return len;
    for (b = 0; b < sess; b++) /* SYN frame: the session id first */
        payload[b] = (uint8_t)(s->link.cfg.session >> (8u * b));
    len += (int)sess;
    s->ow_hdr.version = IT2N_PROTO_VERSION;
    s->ow_hdr.type = m->type;
    s->ow_hdr.flags = (uint8_t)(IT2N_FLAG_REL | (s->step == 0u ? IT2N_FLAG_SYN : 0u));
    s->ow_hdr.len = (uint16_t)len;
    len = it2n_frame_write(s->out, &s->ow_hdr, payload, (size_t)len);
    s->ow_hdr.seq++;
    return len < 0 ? len : 0;
}

int session_step(session *s, uint32_t now)
{
    it2n_msg m;

    if (s->state != SESSION_RUNNING)
        return s->state;
    if (!s->oneway) {
        if (it2n_link_pump(&s->link, now) < 0) {
            s->state = SESSION_FAILED;
            s->fail_code = IT2N_PROTO_ERR_STREAM;
            return s->state;
        }
        (void)it2n_link_poll(&s->link, now);
    }
    /* CONFIGURE is a barrier (docs/protocol.md 4.2 rule 7): sent with
     * nothing else in flight, and nothing follows it until it is answered. */
    while (
        s->state == SESSION_RUNNING && s->step < 4u &&
        (s->oneway || ((s->step == 0u || it2n_link_can_send(&s->link)) &&
                       ((s->step != 1u && !(s->step == 2u && s->puts == 0u)) || it2n_link_pending(&s->link) == 0u)))) {
        if (!build(s, &m)) {
            s->step++; /* PUTs exhausted */
            continue;
        }
        if (m.type == IT2N_MSG_PUT) {
            s->puts++;
            s->entries += m.u.put.count;
        }
        if (s->oneway) {
            if (send_oneway(s, &m) < 0) {
                s->state = SESSION_FAILED;
                s->fail_code = IT2N_PROTO_ERR_STREAM;
            }
        } else if (it2n_link_send(&s->link, &m, now) < 0) {
            s->state = SESSION_FAILED;
            s->fail_code = IT2N_PROTO_ERR_FIELD;
        }
        if (m.type != IT2N_MSG_PUT)
            s->step++;
    }
    if (s->state == SESSION_RUNNING && s->step >= 4u && (s->oneway || it2n_link_pending(&s->link) == 0u))
        s->state = SESSION_DONE;
    return s->state;
}

uint32_t session_idle_ms(const session *s, uint32_t now)
{
    uint32_t t = it2n_link_next_timeout(&s->link, now);
    return t > 50u ? 50u : t;
}
