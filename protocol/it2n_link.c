/*
 * Reliable transport state machine (see it2n_link.h for the contract and
 * docs/protocol.md "Reliable delivery" for the rules on the wire).
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include <string.h>

#include "it2n_link.h"

#define H_EMPTY 0u
#define H_WAITING 1u /* delivered, the application has not answered */
#define H_ANSWERED 2u

/* W sizes the arrays (the build's maximum); l->win is this link's own
 * window, the modulus of the receiver's history and reorder buffer. */
#define W IT2N_PROTO_WINDOW
/* Own window: a constant in minimum builds (MCU: no code for it). */
#define WIN(l) (W == IT2N_PROTO_WINDOW_MIN ? (unsigned)W : (unsigned)(l)->win)
#define SESS IT2N_FRAME_SESSION_SIZE
#define V11 IT2N_PROTO_VERSION
#define V12 IT2N_PROTO_VERSION_12
/* Roles in v1.2: the client asks for a session, the server hands it out. */
#define CLIENT(l) ((l)->cfg.version == V12)
#define SERVER(l) ((l)->cfg.new_session != NULL)

static bool due(uint32_t now, uint32_t deadline)
{
    return (uint32_t)(now - deadline) < 0x80000000u;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v & 0xFFu);
    p[1] = (uint8_t)((v >> 8) & 0xFFu);
    p[2] = (uint8_t)((v >> 16) & 0xFFu);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

/* Time n bytes take on a line of `baud` bits/s (8N1: 10 bits a byte), ms
 * rounded up. 32-bit: n is at most a few maximum frames. */
static uint32_t line_ms(uint32_t n, uint32_t baud)
{
    uint32_t q = baud / 10u; /* bytes per second */
    if (q == 0u)
        q = 1u;
    return (uint32_t)((n / q) * 1000u + ((n % q) * 1000u + q - 1u) / q);
}

uint32_t it2n_link_rto_default(uint32_t baud)
{
    if (baud == 0u)
        return 100u;
    return 20u + line_ms(IT2N_FRAME_MAX_WIRE, baud);
}

/* n wire bytes were written at l->clock: returns when their last byte
 * leaves the line (the line clock; `now` when the baud is unknown). */
static uint32_t line_put(it2n_link *l, uint32_t n)
{
    uint32_t baud = l->cfg.baud;
    if (baud == 0u)
        return l->clock;
    if (due(l->clock, l->line_free)) { /* idle line: starts now */
        l->line_free = l->clock;
        l->line_frac = 0;
    }
    /* ms = n * 10 * 1000 / baud, the remainder kept in line_frac (< baud;
     * n * 10000 stays far below 2^32 for a frame) */
    while (n > 0u) {
        uint32_t k = n > 4096u ? 4096u : n;
        l->line_frac += k * 10000u;
        l->line_free += l->line_frac / baud;
        l->line_frac %= baud;
        n -= k;
    }
    return l->line_free;
}

/* Write a frame and run the line clock. Returns when it leaves. */
static uint32_t frame_out(it2n_link *l, const it2n_frame_hdr *h, const uint8_t *p, size_t len)
{
    int n = it2n_frame_write(l->cfg.out, h, p, len);
    /* A stream error only loses this transmission; the timer retries. */
    return n > 0 ? line_put(l, (uint32_t)n) : l->clock;
}

int it2n_link_init(it2n_link *l, const it2n_link_cfg *cfg)
{
    if (cfg == NULL || cfg->out == NULL || cfg->out->write == NULL || cfg->on_rx == NULL || cfg->rto_ms == 0u)
        return IT2N_ERR_INVAL;
    if (cfg->window != 0u &&
        (cfg->window < IT2N_PROTO_WINDOW_MIN || cfg->window > W || (cfg->window & (cfg->window - 1u)) != 0u))
        return IT2N_ERR_INVAL;
    if ((cfg->version != 0u && cfg->version != V11 && cfg->version != V12) ||
        (cfg->version == V12 && cfg->new_session != NULL))
        return IT2N_ERR_INVAL; /* a v1.2 client does not hand out ids */
    memset(l, 0, sizeof *l);
    l->cfg = *cfg;
    if (l->cfg.rto_max_ms < l->cfg.rto_ms)
        l->cfg.rto_max_ms = l->cfg.rto_ms > UINT32_MAX / 8u ? UINT32_MAX : 8u * l->cfg.rto_ms;
    l->tx_next = cfg->first_seq;
    l->rto = l->cfg.rto_ms; /* until round trips are measured */
    l->win = cfg->window != 0u ? cfg->window : (uint8_t)W;
    l->peer_window = IT2N_PROTO_WINDOW_MIN; /* until the peer's HELLO */
    l->peer_max_payload = IT2N_PROTO_MAX_PAYLOAD;
    l->ver = CLIENT(l) ? (uint8_t)V12 : (uint8_t)V11;
    l->rx_ver = l->ver;
    it2n_frame_decoder_init(&l->dec);
    return IT2N_OK;
}

void it2n_link_set_peer(it2n_link *l, uint8_t window, uint16_t max_payload)
{
    if (window > 0u)
        l->peer_window = window < l->win ? window : l->win;
    if (max_payload > 0u)
        l->peer_max_payload = max_payload < IT2N_PROTO_MAX_PAYLOAD ? max_payload : (uint16_t)IT2N_PROTO_MAX_PAYLOAD;
}

uint8_t it2n_link_window(const it2n_link *l)
{
    return l->win;
}

uint8_t it2n_link_send_window(const it2n_link *l)
{
    return l->peer_window;
}

uint32_t it2n_link_session(const it2n_link *l)
{
    return l->ver == V12 ? l->tag : l->peer_session;
}

uint32_t it2n_link_rto(const it2n_link *l)
{
    return l->rto;
}

uint16_t it2n_link_max_payload(const it2n_link *l)
{
    return l->peer_max_payload;
}

/* ---- sender ------------------------------------------------------------- */

static const it2n_link_slot *oldest_of(const it2n_link *l)
{
    const it2n_link_slot *best = NULL;
    unsigned k;
    for (k = 0; k < W; k++) {
        const it2n_link_slot *s = &l->slot[k];
        /* Age relative to tx_next, which is ahead of every slot in flight. */
        if (s->used && (best == NULL || (uint16_t)(l->tx_next - s->seq) > (uint16_t)(l->tx_next - best->seq)))
            best = s;
    }
    return best;
}

static it2n_link_slot *oldest_slot(it2n_link *l)
{
    const it2n_link_slot *o = oldest_of(l);
    return o == NULL ? NULL : &l->slot[o - l->slot];
}

unsigned it2n_link_pending(const it2n_link *l)
{
    unsigned k, n = l->hello.used;
    for (k = 0; k < W; k++)
        n += l->slot[k].used;
    return n;
}

bool it2n_link_can_send(const it2n_link *l)
{
    const it2n_link_slot *old = oldest_of(l);
    if (CLIENT(l) && l->tag == 0u)
        return false; /* v1.2: nothing but HELLO before the session */
    if (old == NULL)
        return true;
    /* Until the peer accepted our SYN frame, it travels alone; otherwise
     * the span of sequence numbers in flight stays below the window (ours
     * and the peer's) so the receiver's history covers every
     * retransmission and its reorder buffer every frame ahead. */
    if (!l->tx_synced)
        return false;
    return (uint16_t)(l->tx_next - old->seq) < l->peer_window;
}

uint32_t it2n_link_stalled_ms(const it2n_link *l, uint32_t now)
{
    const it2n_link_slot *old = oldest_of(l);
    if (old == NULL && l->hello.used)
        return now - l->hello.first;
    return old == NULL ? 0u : now - old->first;
}

static uint32_t rto_for(const it2n_link *l, unsigned tries)
{
    uint32_t rto = l->rto; /* measured, within rto_ms .. rto_max_ms */
    /* Exponential backoff from the second retransmission on: rto, rto,
     * 2 rto, 4 rto ... up to rto_max_ms (one loss is not an outage). With
     * the line clock (baud known) our own queue never makes a timeout
     * spurious, so a loss is line noise, not congestion: the first
     * three retransmissions keep rto (rto x 4, then 2 rto, 4 rto ...). */
    unsigned flat = l->cfg.baud != 0u ? 4u : 2u;
    while (tries > flat && rto < l->cfg.rto_max_ms) {
        rto = rto > l->cfg.rto_max_ms / 2u ? l->cfg.rto_max_ms : 2u * rto;
        tries--;
    }
    return rto;
}

/* With the line clock: ms the bytes written so far still take to leave. */
static uint32_t backlog(const it2n_link *l)
{
    if (l->cfg.baud == 0u || due(l->clock, l->line_free))
        return 0u;
    return l->line_free - l->clock;
}

/* A frame kept by it2n_link_send, not written yet? (A new frame never
 * overtakes one: they are written in order.) */
static bool any_kept(const it2n_link *l, const it2n_link_slot *but)
{
    unsigned k;
    for (k = 0; k < W; k++)
        if (l->slot[k].used && l->slot[k].tries == 0u && &l->slot[k] != but)
            return true;
    return false;
}

/* New frames are written while at most two maximum frames wait ahead. */
static uint32_t backlog_max(const it2n_link *l)
{
    return line_ms(2u * IT2N_FRAME_MAX_WIRE, l->cfg.baud);
}

static void transmit(it2n_link *l, it2n_link_slot *s, uint32_t now)
{
    it2n_frame_hdr h;
    const uint8_t *p = s->buf + SESS;
    h.version = s->ver;
    h.type = s->type;
    h.flags = (uint8_t)(IT2N_FLAG_REL | s->flags | (s->tries > 0u ? IT2N_FLAG_RETX : 0u));
    h.seq = s->seq;
    h.len = s->len;
    if (s->ver == V12) {
        /* v1.2: every frame carries the session it belongs to. */
        put_u32(s->buf, s->tag);
        p = s->buf;
        h.len = (uint16_t)(s->len + SESS);
    } else if (s->flags & IT2N_FLAG_SYN) {
        /* v1.1: a SYN frame's payload starts with our session id. */
        put_u32(s->buf, l->cfg.session);
        p = s->buf;
        h.len = (uint16_t)(s->len + SESS);
    }
    if (s->tries > 0u) {
        unsigned k;
        uint16_t age = (uint16_t)(l->tx_next - s->seq);
        l->stats.tx_retx++;
        /* Frames sent after this one's first copy are delivered after it
         * (in order): their answers may wait for this copy, so their round
         * trips say nothing about the peer's (Karn's rule, extended). */
        for (k = 0; k < W; k++)
            if (l->slot[k].used && l->slot[k].tries > 0u && (uint16_t)(l->tx_next - l->slot[k].seq) < age)
                l->slot[k].nosample = 1;
    } else {
        s->first = now;
        s->nosample = 0;
    }
    s->held = 0; /* a new copy: only a later GAP says it is held */
    s->probe_wait = 0;
    s->last = now;
    l->stats.tx_frames++;
    l->clock = now;
    s->gone = frame_out(l, &h, p, h.len);
    if (s->tries < 255u)
        s->tries++;
    /* the RTO runs from when this copy has left the line */
    s->deadline = s->gone + rto_for(l, s->tmo + 1u);
}

/* ---- v1.2 sessions (docs/protocol.md 4.1) ------------------------------ */

/* Client: (re)send the HELLO that asks for a session: SYN, session 0, alone. */
static void hello_out(it2n_link *l, uint32_t now)
{
    it2n_link_hello *h = &l->hello;
    it2n_frame_hdr fh;
    fh.version = V12;
    fh.type = IT2N_MSG_HELLO;
    fh.flags = (uint8_t)(IT2N_FLAG_REL | IT2N_FLAG_SYN | (h->tries > 0u ? IT2N_FLAG_RETX : 0u));
    fh.seq = h->seq;
    fh.len = (uint16_t)(SESS + h->len);
    put_u32(h->buf, 0u);
    if (h->tries > 0u)
        l->stats.tx_retx++;
    l->stats.tx_frames++;
    l->clock = now;
    h->deadline = frame_out(l, &fh, h->buf, fh.len) + rto_for(l, h->tries + 1u);
    if (h->tries < 255u)
        h->tries++;
}

/* Client: start asking for a session with the HELLO kept in l->hello. Its
 * number is the next one (not used up: a session's frames carry their own
 * id, so the HELLO's ACK, tagged 0, is never taken for theirs). */
static void hello_start(it2n_link *l, uint32_t now)
{
    l->tag = 0;
    l->tx_synced = 0;
    l->rx_synced = 0;
    l->hello.used = 1;
    l->hello.acked = 0;
    l->hello.tries = 0;
    l->hello.seq = l->tx_next;
    l->hello.first = now;
    l->stats.tx_hellos++;
    hello_out(l, now);
}

static int32_t send_hello(it2n_link *l, const it2n_msg *msg, uint32_t now)
{
    int len;
    if (l->hello.used)
        return IT2N_PROTO_ERR_BUSY; /* one is asking already */
    len = it2n_msg_pack(msg, l->hello.buf + SESS, IT2N_LINK_HELLO_MAX, NULL);
    if (len < 0)
        return len;
    l->hello.len = (uint8_t)len;
    hello_start(l, now);
    return (int32_t)l->hello.seq;
}

/* Finish every frame in flight not framed in version `ver` or, for v1.2,
 * not of session `keep`: it was for a session that is gone. The
 * application gets IT2N_PROTO_ERR_SESSION (not a loss to report). */
static void drop_foreign(it2n_link *l, uint8_t ver, uint32_t keep)
{
    unsigned k;
    for (k = 0; k < W; k++) {
        it2n_link_slot *s = &l->slot[k];
        if (!s->used || (s->ver == ver && (ver != V12 || s->tag == keep)))
            continue;
        s->flags = 0;
        s->used = 0;
        if (l->cfg.on_done != NULL)
            l->cfg.on_done(l->cfg.app, s->seq, s->type, IT2N_PROTO_ERR_SESSION, NULL);
    }
}

static void restart_seq(it2n_link *l, uint32_t now);

/* Server: a v1.2 HELLO with session 0 arrived: hand out a new session id
 * (never 0, none in use on this link), for our answer and the peer's
 * frames to come. What we had in flight was for a session that is gone. */
static void offer(it2n_link *l)
{
    uint32_t n = 0;
    unsigned k, tries;
    for (tries = 0; tries < 8u; tries++) {
        bool clash;
        n = l->cfg.new_session(l->cfg.app);
        clash = n == 0u || n == l->tag || n == l->peer_session;
        for (k = 0; k < 4u; k++)
            clash = clash || n == l->offer[k];
        if (!clash)
            break;
        n = 0;
    }
    if (n == 0u) /* the source keeps repeating itself: derive one */
        n = ((l->tag ^ l->offer[0]) * 2654435761u + 0x9E3779B9u) | 1u;
    for (k = 3u; k > 0u; k--)
        l->offer[k] = l->offer[k - 1u];
    l->offer[0] = n;
    l->tag = n;
    l->ver = V12;
    drop_foreign(l, V12, n);
    l->tx_synced = 0; /* our answer starts a sequence of this session */
}

static bool offered(const it2n_link *l, uint32_t t)
{
    unsigned k;
    for (k = 0; k < 4u; k++)
        if (t != 0u && l->offer[k] == t)
            return true;
    return false;
}

/* Server: the peer took up session t (its first frame carries it). */
static void establish(it2n_link *l, uint32_t t, uint32_t now)
{
    memset(l->offer, 0, sizeof l->offer);
    if (l->tag != t) { /* it took an earlier offer: answers of later ones go */
        l->tag = t;
        drop_foreign(l, V12, t);
        restart_seq(l, now);
    }
}

/* Client: the server's HELLO gives session t: the HELLO is answered, the
 * frames kept while asking go on in a new sequence of that session. */
static void adopt(it2n_link *l, uint32_t t, uint32_t now)
{
    unsigned k;
    uint16_t seq = l->hello.seq;
    l->tag = t;
    for (k = 0; k < W; k++)
        if (l->slot[k].used) {
            l->slot[k].tag = t;
            l->slot[k].flags = 0;
            l->slot[k].held = 0; /* held by a receiver that is gone */
        }
    if (l->hello.used) {
        l->hello.used = 0;
        l->stats.tx_acked++;
        if (l->cfg.on_done != NULL)
            l->cfg.on_done(l->cfg.app, seq, IT2N_MSG_HELLO, IT2N_OK, NULL);
    }
    restart_seq(l, now);
}

int32_t it2n_link_send(it2n_link *l, const it2n_msg *msg, uint32_t now)
{
    it2n_link_slot *s = NULL;
    unsigned k;
    int len;

    if (msg->type == IT2N_MSG_ACK || msg->type == IT2N_MSG_NACK || msg->type == IT2N_MSG_GAP ||
        msg->type == IT2N_MSG_RCVD)
        return IT2N_PROTO_ERR_TYPE; /* link-internal, never reliable */
    if (CLIENT(l) && l->tag == 0u && msg->type == IT2N_MSG_HELLO)
        return send_hello(l, msg, now);
    if (!it2n_link_can_send(l))
        return IT2N_PROTO_ERR_BUSY;
    for (k = 0; k < W && s == NULL; k++)
        if (!l->slot[k].used)
            s = &l->slot[k];
    if (s == NULL)
        return IT2N_PROTO_ERR_BUSY;
    len = it2n_msg_pack(msg, s->buf + SESS, IT2N_PROTO_MAX_PAYLOAD, NULL);
    if (len < 0)
        return len;
    if (len > (int)l->peer_max_payload)
        return IT2N_PROTO_ERR_NOSPACE; /* the peer could not take it */
    s->used = 1;
    s->tries = 0;
    s->tmo = 0;
    s->held = 0;
    s->ver = l->ver;
    s->tag = l->tag;
    s->type = msg->type;
    s->flags = l->tx_synced ? 0u : IT2N_FLAG_SYN;
    s->seq = l->tx_next++;
    s->len = (uint16_t)len;
    l->clock = now;
    if (l->tx_synced && (backlog(l) > backlog_max(l) || any_kept(l, s))) {
        /* The line is busy for a while: keep the frame until it has room
         * (it2n_link_poll), so a retransmission is never queued behind a
         * window of new frames (docs/protocol.md 4.2 rule 3). */
        s->first = s->last = s->gone = now;
        s->deadline = now;
        return (int32_t)s->seq;
    }
    transmit(l, s, now);
    return (int32_t)s->seq;
}

static void finish(it2n_link *l, it2n_link_slot *s, int code, const it2n_msg_nack *nack)
{
    uint16_t seq = s->seq;
    uint8_t type = s->type;
    if (s->flags & IT2N_FLAG_SYN)
        l->tx_synced = 1;
    s->used = 0;
    if (l->cfg.on_done != NULL)
        l->cfg.on_done(l->cfg.app, seq, type, code, nack);
}

/* The receiver's reorder buffer is gone (it starts a new sequence): no
 * frame of ours is held any more. */
static void unhold_all(it2n_link *l)
{
    unsigned k;
    for (k = 0; k < W; k++)
        l->slot[k].held = 0;
}

/* Our SYN frame `seq` was answered. After a resync (the peer restarted and
 * took up the sequence at that frame) a frame after it may already have
 * been answered by the peer's previous life: the peer then waits for it
 * forever. So unless the next frame in flight follows directly, it starts
 * a new sequence too. */
static void syn_answered(it2n_link *l, uint16_t seq, uint32_t now)
{
    it2n_link_slot *o = oldest_slot(l);
    if (o == NULL || o->seq == (uint16_t)(seq + 1u) || !l->tx_synced)
        return;
    unhold_all(l);
    l->tx_synced = 0;
    o->flags |= IT2N_FLAG_SYN;
    transmit(l, o, now);
}

unsigned it2n_link_drop_tx(it2n_link *l)
{
    unsigned k, n = 0;
    for (k = 0; k < W; k++) {
        it2n_link_slot *s = &l->slot[k];
        if (!s->used)
            continue;
        s->flags = 0; /* dropped, not accepted: no implied sync */
        finish(l, s, IT2N_PROTO_ERR_DOWN, NULL);
        n++;
    }
    if (l->hello.used) {
        l->hello.used = 0;
        n++;
        if (l->cfg.on_done != NULL)
            l->cfg.on_done(l->cfg.app, l->hello.seq, IT2N_MSG_HELLO, IT2N_PROTO_ERR_DOWN, NULL);
    }
    l->stats.tx_dropped += n;
    l->tx_synced = 0;
    return n;
}

static it2n_link_slot *slot_of(it2n_link *l, uint16_t seq)
{
    unsigned k;
    for (k = 0; k < W; k++)
        if (l->slot[k].used && l->slot[k].seq == seq)
            return &l->slot[k];
    return NULL;
}

/* The receiver's state does not match ours (it restarted, or it started
 * its sequence on a stale copy of an old SYN frame): resend the oldest
 * frame with SYN, the others follow once it is accepted. */
static void resync(it2n_link *l, uint32_t now)
{
    it2n_link_slot *old = oldest_slot(l);
    if (!l->tx_synced || old == NULL)
        return; /* already resyncing, or nothing to resync */
    unhold_all(l);
    l->tx_synced = 0;
    l->stats.tx_resyncs++;
    old->flags |= IT2N_FLAG_SYN;
    transmit(l, old, now);
}

/* Start a new sequence with the oldest frame in flight (SYN); the others
 * follow once it is answered. */
static void restart_seq(it2n_link *l, uint32_t now)
{
    it2n_link_slot *old = oldest_slot(l);
    unhold_all(l);
    l->tx_synced = 0;
    if (old == NULL)
        return;
    old->flags |= IT2N_FLAG_SYN;
    transmit(l, old, now);
}

/* GAP from the receiver: it just kept frame `have` but misses `seq`, and
 * holds the frames whose bits are set in `held` (bit k: seq + 1 + k; v1.1:
 * `have` only). Held frames are marked: they are not resent on timeout
 * while an older frame is missing (selective acknowledgement,
 * docs/protocol.md 4.2 rule 4). Each missing frame from seq up to `have`
 * whose last copy left no later than the copy of `have` it got (a line
 * keeps order) was lost: it is sent again now rather than at its timeout.
 * A copy sent after `have` may still be on its way: wait. If `have` is no
 * longer in flight, a quarter RTO since the last copy. If seq is not in
 * flight but `have` is and seq comes before it, the receiver waits for a
 * frame we count as answered: its sequence is not ours (it synced on a
 * stale SYN copy), so we resync (docs/protocol.md 4.2 rule 5). */
static void on_gap(it2n_link *l, uint16_t seq, uint16_t have, uint64_t held, uint32_t now)
{
    it2n_link_slot *s = slot_of(l, seq), *h = slot_of(l, have);
    uint16_t span = (uint16_t)(have - seq);
    unsigned k;
    if (!l->tx_synced || h == s || span == 0u || span >= 0x8000u)
        return;
    if (s == NULL) {
        if (h != NULL && (uint16_t)(l->tx_next - seq) > (uint16_t)(l->tx_next - have))
            resync(l, now);
        return;
    }
    if (span <= 64u)
        held |= (uint64_t)1u << (span - 1u); /* `have` itself */
    for (k = 0; k < W; k++) {
        it2n_link_slot *o = &l->slot[k];
        uint16_t d = (uint16_t)(o->seq - seq);
        if (!o->used || d == 0u || d > 64u || !((held >> (d - 1u)) & 1u) || o->held)
            continue;
        o->held = 1;
        o->nosample = 1; /* its answer waits for the missing frame */
        l->stats.tx_held++;
    }
    for (k = 0; k < W; k++) {
        it2n_link_slot *o = &l->slot[k];
        if (!o->used || o->held || (uint16_t)(o->seq - seq) >= span)
            continue; /* answered, held, or not before `have` */
        if (h != NULL ? (int32_t)(h->last - o->last) >= 0 : (uint32_t)(now - o->last) >= (l->cfg.rto_ms + 3u) / 4u) {
            l->stats.tx_fast_retx++;
            transmit(l, o, now);
        }
    }
}

/* A round-trip sample (docs/protocol.md 4.2 rule 3): the first answer
 * (ACK, NACK or RCVD) to frame s, or to a HELLO, sent once (Karn's
 * rule: the answer to a retransmitted frame may be the first copy's), not held by a GAP or
 * deferred (RCVD) and not sent while an older frame was retransmitted.
 * It runs from when the frame left the line (with the line clock) or was
 * written. SRTT and RTTVAR as RFC 6298 (gains 1/8 and 1/4, integer ms,
 * scaled by 8 and 4); the RTO is SRTT + max(1, 4 RTTVAR) within rto_ms ..
 * rto_max_ms, so that a peer whose answers come late now and then (a
 * loaded machine, a USB adapter's latency) is not taken for a lossy one. */
static void rtt_update(it2n_link *l, uint32_t r)
{
    uint32_t rto;
    int32_t err;
    if (r > l->cfg.rto_max_ms)
        r = l->cfg.rto_max_ms; /* beyond the cap says nothing more */
    if (r > 0x00FFFFFFu)
        r = 0x00FFFFFFu; /* keep r x 8 within 32 bits */
    if (!l->rtt_valid) {
        l->srtt8 = r * 8u;
        l->rttvar4 = r * 2u; /* RTTVAR = R / 2 */
        l->rtt_valid = 1;
    } else {
        err = (int32_t)r - (int32_t)(l->srtt8 >> 3);
        l->srtt8 = (uint32_t)((int32_t)l->srtt8 + err);
        if (err < 0)
            err = -err;
        l->rttvar4 = (uint32_t)((int32_t)l->rttvar4 + err - (int32_t)(l->rttvar4 >> 2));
    }
    rto = (l->srtt8 >> 3) + (l->rttvar4 > 1u ? l->rttvar4 : 1u);
    if (rto < l->cfg.rto_ms)
        rto = l->cfg.rto_ms;
    if (rto > l->cfg.rto_max_ms)
        rto = l->cfg.rto_max_ms;
    l->rto = rto;
}

static void rtt_sample(it2n_link *l, const it2n_link_slot *s, uint32_t now)
{
    if (s->tries != 1u || s->held != 0u || s->nosample)
        return;
    rtt_update(l, due(now, s->gone) ? now - s->gone : 0u);
}

/* How long a frame answered RCVD waits for its deferred answer: twice
 * the deferrals seen lately, at least 2 RTO, at most rto_max_ms. */
static uint32_t rcvd_wait(const it2n_link *l)
{
    uint32_t w = l->defer_ms > l->rto ? l->defer_ms : l->rto;
    return w > l->cfg.rto_max_ms / 2u ? l->cfg.rto_max_ms : 2u * w;
}

/* In-order delivery (docs/protocol.md 4.2 rule 3): the peer has just
 * answered frame s for the first time (RCVD, ACK or NACK), so it is
 * running and works through its input in order: the frames sent after s
 * come next. Their timers run
 * from now at the earliest: a peer working through its input (a loaded
 * machine, an fsync) answers them one by one, each later than its
 * departure plus an RTO, and none of them is lost. TCP restarts its timer
 * on every ACK of new data likewise (RFC 6298, 5.3). A frame answered
 * RCVD waits its RCVD wait from now; frames held by a GAP or waiting
 * behind an older one keep their timers. */
static void delivered(it2n_link *l, const it2n_link_slot *s, uint32_t now)
{
    uint16_t age = (uint16_t)(l->tx_next - s->seq), next = 0;
    /* An ACK after a RCVD shows the application done, not a new delivery:
     * it restarts only the frame right after s (a deferred ACK of an
     * older frame must not keep postponing a lost one) */
    bool all = s->held != 2u;
    unsigned k;
    for (k = 0; k < W && !all; k++) {
        const it2n_link_slot *o = &l->slot[k];
        uint16_t a = (uint16_t)(l->tx_next - o->seq);
        if (o->used && o->tries > 0u && a < age && a > next)
            next = a;
    }
    for (k = 0; k < W; k++) {
        it2n_link_slot *o = &l->slot[k];
        uint16_t a = (uint16_t)(l->tx_next - o->seq);
        uint32_t t;
        if (!o->used || o->tries == 0u || o->held == 1u || o->probe_wait != 0u || a >= age || (!all && a != next))
            continue;
        t = now + (o->held == 2u ? rcvd_wait(l) : rto_for(l, o->tmo + 1u));
        if (due(t, o->deadline))
            o->deadline = t;
    }
}

/* RCVD from the receiver: it has frame seq and will answer it later. No
 * retransmission before twice the time the peer's deferred answers take
 * lately (an fsync on a loaded machine), at least 2 RTO, at most
 * rto_max_ms: the answer may still be lost, then a retransmission gets
 * it repeated. */
static void on_rcvd(it2n_link *l, uint16_t seq, uint32_t now)
{
    it2n_link_slot *s = slot_of(l, seq);
    uint32_t t = now + rcvd_wait(l);
    /* Before the SYN frame is answered only its own RCVD counts: the
     * receiver has started the sequence with it (an fsync may defer its
     * answer, as for the first CONFIGURE of a session). */
    if (s == NULL || s->ver != V12 || s->tag != l->tag || (!l->tx_synced && !(s->flags & IT2N_FLAG_SYN)))
        return;
    if (s->held != 2u) {
        rtt_sample(l, s, now); /* its delivery took a round trip */
        l->stats.rx_rcvd++;
        s->rcvd = now;
        delivered(l, s, now);
    }
    s->held = 2u;
    if (due(t, s->deadline))
        s->deadline = t;
}

/* Is an older frame than s in flight and not held (missing at the
 * receiver, or not yet known to be there)? */
static bool older_missing(const it2n_link *l, const it2n_link_slot *s)
{
    unsigned k;
    uint16_t age = (uint16_t)(l->tx_next - s->seq);
    for (k = 0; k < W; k++) {
        const it2n_link_slot *o = &l->slot[k];
        if (o->used && !o->held && (uint16_t)(l->tx_next - o->seq) > age)
            return true;
    }
    return false;
}

/* After an answer: a held frame with no older frame missing is being
 * delivered by the receiver now; its own answer is due within an RTO, so
 * its timer runs again from now. */
static void release_held(it2n_link *l, uint32_t now)
{
    unsigned k;
    for (k = 0; k < W; k++) {
        it2n_link_slot *s = &l->slot[k];
        uint32_t t;
        if (!s->used || s->held != 1u || older_missing(l, s))
            continue;
        s->held = 0;
        t = now + rto_for(l, s->tmo + 1u);
        if (due(t, s->deadline))
            s->deadline = t;
    }
}

/* A frame sent once was answered at `now` though the line clock has it
 * leave at `gone`: the line is faster than the baud rate says (a USB
 * adapter, a pty). Everything written before it has left too: move the
 * clock back by the difference, and every later departure with it, so
 * that the estimate never runs ahead of the line. */
static void line_sync(it2n_link *l, uint32_t gone, uint32_t now)
{
    uint32_t d;
    unsigned k;
    if (l->cfg.baud == 0u || due(now, gone))
        return;
    d = gone - now;
    l->line_free -= d;
    for (k = 0; k < W; k++) {
        it2n_link_slot *o = &l->slot[k];
        uint32_t e;
        if (!o->used || due(now, o->gone))
            continue;
        e = o->gone - now < d ? o->gone - now : d;
        o->gone -= e;
        o->deadline -= e;
    }
}

/* An answer to our v1.2 HELLO (session 0): the ACK says the server has
 * it (its HELLO with the session follows); a NACK ends it. */
static void hello_answer(it2n_link *l, const it2n_msg *m, uint32_t now)
{
    l->stats.rx_acks++;
    if (l->hello.tries == 1u && !l->hello.acked)
        rtt_update(l, now - l->hello.first); /* the first round trip (sent once: Karn) */
    if (m->type == IT2N_MSG_ACK) {
        /* Wait for the server's HELLO, which it retransmits itself; ask
         * again only if it stays away (the ACK was a stale copy). */
        l->hello.acked = 1;
        l->hello.deadline = now + 4u * rto_for(l, l->hello.tries);
        return;
    }
    l->hello.used = 0;
    l->stats.tx_nacked++;
    if (l->cfg.on_done != NULL)
        l->cfg.on_done(l->cfg.app, l->hello.seq, IT2N_MSG_HELLO, m->u.nack.code, &m->u.nack);
}

/* Frame s is answered (ACK or NACK) at now. */
static void answered(it2n_link *l, const it2n_link_slot *s, uint32_t now)
{
    l->stats.rx_acks++;
    delivered(l, s, now);
    if (s->tries == 1u)
        line_sync(l, s->gone, now);
    if (s->held == 2u) { /* how long the peer took after its RCVD */
        uint32_t d = now - s->rcvd;
        l->defer_ms = d >= l->defer_ms ? d : l->defer_ms - (l->defer_ms - d) / 8u;
    }
}

/* Frame s is ACKed. */
static void acked(it2n_link *l, it2n_link_slot *s, uint32_t now)
{
    uint16_t seq = s->seq, age = (uint16_t)(l->tx_next - s->seq);
    uint32_t acked_last = s->last;
    bool syn = (s->flags & IT2N_FLAG_SYN) != 0u;
    unsigned k;
    answered(l, s, now);
    l->stats.tx_acked++;
    finish(l, s, IT2N_OK, NULL);
    if (syn)
        syn_answered(l, seq, now);
    release_held(l, now);
    /* Frames are delivered in order: an older frame still unanswered
     * whose last copy left no later than the acknowledged one's was
     * delivered too, and its answer was lost (or is deferred, then the
     * copy is ignored): send it again now, not at its timeout. */
    for (k = 0; k < W; k++) {
        it2n_link_slot *o = &l->slot[k];
        if (o->used && l->tx_synced && (uint16_t)(l->tx_next - o->seq) > age && (int32_t)(acked_last - o->last) >= 0) {
            l->stats.tx_fast_retx++;
            transmit(l, o, now);
        }
    }
}

/* ACK or NACK m, framed in version ver with session tag (v1.2). */
static void on_answer(it2n_link *l, const it2n_msg *m, uint8_t ver, uint32_t tag, uint32_t now)
{
    uint16_t seq = m->type == IT2N_MSG_ACK ? m->u.ack.seq : m->u.nack.seq;
    it2n_link_slot *s = NULL;
    unsigned k;
    /* Only an older peer's VERSION refusal is read across versions. */
    bool any = m->type == IT2N_MSG_NACK && m->u.nack.code == IT2N_PROTO_ERR_VERSION && ver < V12;

    if (l->hello.used && seq == l->hello.seq && ((ver == V12 && tag == 0u) || any)) {
        hello_answer(l, m, now);
        return;
    }
    if (m->type == IT2N_MSG_ACK && m->u.ack.acked != 0u && ver == V12) {
        /* v1.2: the frames it names were ACKed too (their own ACK may have
         * been lost): end them first, oldest first, as if ACKed. */
        for (k = 64u; k-- > 0u;) {
            it2n_link_slot *o;
            if (!((m->u.ack.acked >> k) & 1u))
                continue;
            o = slot_of(l, (uint16_t)(seq - 1u - k));
            if (o != NULL && o->ver == V12 && o->tag == tag) {
                l->stats.rx_acks_implied++;
                acked(l, o, now);
            }
        }
    }
    for (k = 0; k < W && s == NULL; k++)
        if (l->slot[k].used && l->slot[k].seq == seq &&
            (any || (l->slot[k].ver == V12 ? ver == V12 && l->slot[k].tag == tag : ver != V12)))
            s = &l->slot[k];
    if (s == NULL) {
        l->stats.rx_stale_acks++;
        return;
    }
    if (m->type == IT2N_MSG_NACK && m->u.nack.code == IT2N_PROTO_ERR_SESSION && s->ver == V12) {
        /* The peer does not know the session of this frame. A client
         * whose session it is asks for a new one (the server restarted)
         * and sends the frame again in it; anything else is gone. */
        l->stats.tx_nacked++;
        if (CLIENT(l)) {
            /* kept: it goes again in the new session */
            if (tag == l->tag && !l->hello.used && l->hello.len > 0u)
                hello_start(l, now);
            return;
        }
        s->flags = 0;
        finish(l, s, IT2N_PROTO_ERR_SESSION, &m->u.nack);
        return;
    }
    rtt_sample(l, s, now); /* its own answer (not one implied by a later ACK) */
    if (m->type == IT2N_MSG_ACK) {
        acked(l, s, now);
        return;
    }
    answered(l, s, now);
    if (m->u.nack.code == IT2N_PROTO_ERR_NOSYNC) {
        /* Peer lost its state (restart) or holds another sequence. */
        resync(l, now);
    } else {
        bool syn = (s->flags & IT2N_FLAG_SYN) != 0u;
        l->stats.tx_nacked++;
        finish(l, s, m->u.nack.code, &m->u.nack);
        if (syn)
            syn_answered(l, seq, now);
        release_held(l, now);
    }
}

/* Silence on the peer's line long enough to say nothing is queued behind
 * its last bytes: 2 ms plus the time of 64 bytes (read granularity). */
static uint32_t quiet_ms(const it2n_link *l)
{
    return 2u + line_ms(64u, l->cfg.baud);
}

/* The peer's bytes are still arriving: some came within quiet_ms, or a
 * frame of it is half received and its last byte came within the minimum
 * RTO (the rest is on its way: a peer or relay held by the scheduler
 * mid-frame; a frame whose delimiter was corrupted holds nothing long). */
static bool reverse_busy(const it2n_link *l, uint32_t now)
{
    uint32_t quiet = (uint32_t)(now - l->rx_last);
    return l->rx_heard && (quiet < quiet_ms(l) || (l->dec.started && quiet < l->cfg.rto_ms));
}

/* Will the ACK of a later frame name s (v1.2 `acked`, 64 frames back)?
 * A later frame of its session is in flight. */
static bool acked_later(const it2n_link *l, const it2n_link_slot *s)
{
    uint16_t age = (uint16_t)(l->tx_next - s->seq);
    unsigned k;
    if (s->ver != V12)
        return false;
    for (k = 0; k < W; k++) {
        const it2n_link_slot *o = &l->slot[k];
        uint16_t a = (uint16_t)(l->tx_next - o->seq);
        if (o->used && o->tries > 0u && o->ver == V12 && o->tag == s->tag && a < age && (uint16_t)(age - a) <= 64u)
            return true;
    }
    return false;
}

/* Oldest first (docs/protocol.md 4.2 rule 3): frame s is due, but an
 * older frame is still unanswered (no ACK, NACK or RCVD, not held by a
 * GAP). The receiver delivers in order, so s cannot be answered before
 * that frame, and were s alone lost, the older frame's delivery would
 * bring a GAP: s's timeout says nothing yet. A stalled peer or line would
 * otherwise cost a retransmission per frame in flight; as in TCP (RFC
 * 6298, 5.4) only the earliest is resent. s waits for that frame's next
 * timeout (after it, if it is due now too); anything heard from the peer
 * starts its timer again (it2n_link_input). True: s waits. */
static bool probe_out(it2n_link *l, it2n_link_slot *s, uint32_t now)
{
    uint16_t age = (uint16_t)(l->tx_next - s->seq);
    unsigned k;
    for (k = 0; k < W; k++) {
        const it2n_link_slot *o = &l->slot[k];
        if (!o->used || o->held != 0u || o->tries == 0u || (uint16_t)(l->tx_next - o->seq) <= age)
            continue; /* not an older frame sent and not held */
        if (o->tries > 1u && !due(now, o->deadline) &&
            (o->tmo == 0u || (l->rx_heard && (int32_t)(l->rx_last - o->last) >= 0)))
            continue; /* resent, the line loses frames: both recover at once (but one probe into silence) */
        if (due(now, o->deadline)) {
            s->deadline = now; /* after it, on the next poll */
            return true;
        }
        s->deadline = o->deadline;
        s->probe_wait = 1;
        return true;
    }
    return false;
}

/* Newer frames that left the line after the peer last spoke, with no
 * word from it since: from this many on, silence is taken for a stall
 * (each frame or its GAP is lost about one time in three on a line with
 * 10 % drops and 10 % corruption each way: both, one time in eight; and
 * the daemon keeps only 4 frames in flight on a serial line). */
#define STALL_UNHEARD 2u

/* A stall, not a loss (docs/protocol.md 4.2 rule 3): frame s is due, the
 * peer has been silent for a whole RTO, and either STALL_UNHEARD newer
 * frames left the line after the peer last spoke, at least half the
 * minimum RTO ago (had only s been lost, the peer would have answered each
 * with a GAP), or an older frame waits for this silence already. Silence after frames the peer should have
 * answered says the peer or the line is not running (a loaded machine
 * holds a process for 40-100 ms), not that frames were lost: s waits
 * until half the backoff cap after its timer started (4 minimum RTOs by
 * default, 128 ms at 921 600 Bd) or until the peer speaks, when
 * its timer starts again from then (probe_heard). Only once per timeout:
 * if the silence lasts, the probe goes. True: s waits. */
static bool silent_stall(it2n_link *l, it2n_link_slot *s, uint32_t now)
{
    uint32_t rto = rto_for(l, s->tmo + 1u);
    uint16_t age = (uint16_t)(l->tx_next - s->seq);
    bool stall = false;
    unsigned k, unheard = 0;
    uint32_t half = l->cfg.rto_max_ms / 2u;
    if (s->probe_wait == 2u || rto >= half || (l->rx_heard && (uint32_t)(now - l->rx_last) < rto))
        return false;
    for (k = 0; k < W && !stall; k++) {
        const it2n_link_slot *o = &l->slot[k];
        if (!o->used || o->tries == 0u || o == s)
            continue;
        if ((uint16_t)(l->tx_next - o->seq) > age)
            stall = o->probe_wait == 2u; /* an older frame waits so */
        else if (o->held == 0u && due(now, o->gone + l->cfg.rto_ms / 2u) &&
                 (!l->rx_heard || (int32_t)(o->gone - l->rx_last) >= 0))
            stall = ++unheard >= STALL_UNHEARD;
    }
    if (stall) {
        s->deadline = now + (half - rto);
        s->probe_wait = 2u;
        l->stats.tx_stall_waits++;
    }
    return stall;
}

/* Something came from the peer: it runs again. The timers of frames
 * waiting behind a probe start again from now (their answers, if they
 * were delivered, follow; a peer that wakes from a stall may take a while
 * to work through its input). */
static void probe_heard(it2n_link *l, uint32_t now)
{
    unsigned k;
    for (k = 0; k < W; k++) {
        it2n_link_slot *s = &l->slot[k];
        if (!s->used || !s->probe_wait)
            continue;
        s->probe_wait = 0;
        s->deadline = now + rto_for(l, s->tmo + 1u);
    }
}

/* Write the frames kept by it2n_link_send (never sent yet), oldest first,
 * while the line has room. */
static void send_kept(it2n_link *l, uint32_t now)
{
    unsigned n;
    if (!l->tx_synced)
        return; /* after the SYN frame is answered */
    for (n = 0; n < W && backlog(l) <= backlog_max(l); n++) {
        it2n_link_slot *o = NULL;
        unsigned k;
        for (k = 0; k < W; k++) {
            it2n_link_slot *c = &l->slot[k];
            if (c->used && c->tries == 0u &&
                (o == NULL || (uint16_t)(l->tx_next - c->seq) > (uint16_t)(l->tx_next - o->seq)))
                o = c;
        }
        if (o == NULL)
            break;
        transmit(l, o, now);
        l->clock = now;
    }
}

int it2n_link_poll(it2n_link *l, uint32_t now)
{
    unsigned k;
    l->clock = now;
    send_kept(l, now);
    if (l->hello.used && due(now, l->hello.deadline)) {
        if (l->cfg.max_tries != 0u && l->hello.tries >= l->cfg.max_tries) {
            l->hello.used = 0;
            l->stats.tx_timeouts++;
            if (l->cfg.on_done != NULL)
                l->cfg.on_done(l->cfg.app, l->hello.seq, IT2N_MSG_HELLO, IT2N_PROTO_ERR_TIMEOUT, NULL);
        } else {
            l->hello.acked = 0;
            hello_out(l, now);
        }
    }
    for (k = 0; k < W; k++) {
        it2n_link_slot *s = &l->slot[k];
        if (!s->used || !due(now, s->deadline) || s->tries == 0u)
            continue; /* not due, or kept for send_kept */
        if (CLIENT(l) && l->tag == 0u) {
            /* kept until the server's HELLO gives the session */
            s->deadline = now + rto_for(l, s->tmo + 1u);
            continue;
        }
        if (s->held == 1u && older_missing(l, s)) {
            /* The receiver has it: only the missing frames before it are
             * resent (selective acknowledgement). */
            s->deadline = now + rto_for(l, s->tmo + 1u);
            continue;
        }
        if (s->held == 2u && acked_later(l, s)) {
            /* Delivered (RCVD), its answer deferred: a later ACK names it
             * if this one's is lost (v1.2 `acked`), so no copy is needed
             * while a later frame is in flight (4.2 rule 4c). */
            s->deadline = now + rcvd_wait(l);
            continue;
        }
        if (probe_out(l, s, now))
            continue; /* oldest first */
        if (silent_stall(l, s, now))
            continue; /* the peer stalls: no loss said so */
        if (l->cfg.baud != 0u && reverse_busy(l, now)) {
            /* The peer's bytes are still arriving: its answer may be
             * queued behind them (at most a window of maximum frames).
             * Look again once its line is quiet, or at that bound. */
            uint32_t cap = s->gone + rto_for(l, s->tmo + 1u) + line_ms(WIN(l) * IT2N_FRAME_MAX_WIRE, l->cfg.baud);
            if (!due(now, cap)) {
                uint32_t again = now + quiet_ms(l);
                s->deadline = due(again, cap) ? cap : again;
                continue;
            }
        }
        if (l->cfg.max_tries != 0u && s->tries >= l->cfg.max_tries) {
            /* Lost for good: report it and resync the rest, so the
             * receiver does not wait for this sequence number forever. */
            l->stats.tx_timeouts++;
            s->flags = 0;
            finish(l, s, IT2N_PROTO_ERR_TIMEOUT, NULL);
            l->tx_synced = 0;
            continue;
        }
        if (!l->tx_synced) {
            it2n_link_slot *old = oldest_slot(l);
            if (old != s) {
                s->deadline = now + rto_for(l, s->tmo + 1u); /* wait for SYN */
                continue;
            }
            s->flags |= IT2N_FLAG_SYN;
        }
        if (s->tmo < 255u)
            s->tmo++;
        transmit(l, s, now);
    }
    return IT2N_OK;
}

uint32_t it2n_link_next_timeout(const it2n_link *l, uint32_t now)
{
    uint32_t best = UINT32_MAX;
    unsigned k;
    if (l->hello.used)
        best = due(now, l->hello.deadline) ? 0u : l->hello.deadline - now;
    for (k = 0; k < W; k++) {
        const it2n_link_slot *s = &l->slot[k];
        uint32_t left;
        if (!s->used)
            continue;
        if (s->tries == 0u) { /* kept: when the line has room */
            uint32_t b = backlog(l), m = backlog_max(l);
            uint32_t past = (uint32_t)(now - l->clock); /* clock is our last call */
            b = b > past ? b - past : 0u;
            left = b > m ? b - m : 0u;
        } else
            left = due(now, s->deadline) ? 0u : s->deadline - now;
        if (left < best)
            best = left;
    }
    return best;
}

/* ---- receiver ----------------------------------------------------------- */

/* Send ACK/NACK a, framed with version `ver` (ours, or an older peer's so
 * that it can read the refusal: ACK and NACK never change layout); in
 * v1.2 after the session `tag` of the frame answered. */
static void send_answer_acked(it2n_link *l, const it2n_msg_nack *a, uint8_t ver, uint32_t tag, uint64_t acked)
{
    it2n_msg m;
    uint8_t buf[64 + SESS];
    size_t off = ver == V12 ? SESS : 0u;
    it2n_frame_hdr h;
    int len;

    memset(&m, 0, sizeof m);
    if (a->code == 0) {
        m.type = IT2N_MSG_ACK;
        m.u.ack.seq = a->seq;
        m.u.ack.acked = ver == V12 ? acked : 0u;
    } else {
        m.type = IT2N_MSG_NACK;
        m.u.nack = *a;
    }
    len = it2n_msg_pack(&m, buf + off, sizeof buf - off, NULL);
    if (len < 0)
        return;
    if (off > 0u)
        put_u32(buf, tag);
    h.version = ver;
    h.type = m.type;
    h.flags = 0;
    h.seq = 0;
    h.len = (uint16_t)((size_t)len + off);
    (void)frame_out(l, &h, buf, h.len);
}

static void send_answer_vt(it2n_link *l, const it2n_msg_nack *a, uint8_t ver, uint32_t tag)
{
    send_answer_acked(l, a, ver, tag, 0u);
}

static void send_answer_v(it2n_link *l, const it2n_msg_nack *a, uint8_t ver)
{
    send_answer_vt(l, a, ver, 0u);
}

static it2n_link_hist *hist_find(it2n_link *l, uint16_t seq);

/* An answer within the current receive sequence. A v1.2 ACK also names
 * the frames of the last W that were ACKed (bit k: seq - 1 - k), so that
 * one lost ACK costs no retransmission (docs/protocol.md 4.3). */
static void send_answer(it2n_link *l, const it2n_msg_nack *a)
{
    uint64_t acked = 0;
    unsigned k;
    for (k = 0; a->code == 0 && l->rx_ver == V12 && k + 1u < WIN(l); k++) {
        const it2n_link_hist *h = hist_find(l, (uint16_t)(a->seq - 1u - k));
        if (h != NULL && h->state == H_ANSWERED && h->answer.code == 0)
            acked |= (uint64_t)1u << k;
    }
    send_answer_acked(l, a, l->rx_ver, l->peer_session, acked);
}

/* v1.2: RCVD (docs/protocol.md 4.3 rule 3): frame seq of the current
 * sequence was delivered and its answer is pending (the application
 * deferred it: an fsync, a request queued behind a response run), so its
 * sender stops resending it at each RTO. v1.1 peers never get it. */
static void send_rcvd(it2n_link *l, uint16_t seq)
{
    it2n_msg m;
    uint8_t buf[SESS + 2u];
    it2n_frame_hdr h;
    if (l->rx_ver != V12)
        return;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_RCVD;
    m.u.rcvd.seq = seq;
    put_u32(buf, l->peer_session);
    if (it2n_msg_pack(&m, buf + SESS, 2u, NULL) != 2)
        return;
    h.version = V12;
    h.type = IT2N_MSG_RCVD;
    h.flags = 0;
    h.seq = 0;
    h.len = (uint16_t)sizeof buf;
    (void)frame_out(l, &h, buf, h.len);
    l->stats.tx_rcvd++;
}

static void nack_plain(it2n_msg_nack *a, uint16_t seq, int code)
{
    memset(a, 0, sizeof *a);
    a->seq = seq;
    a->code = (int16_t)code;
    a->i = a->j = -1;
    a->fp = a->ch = -1;
}

static it2n_link_hist *hist_find(it2n_link *l, uint16_t seq)
{
    it2n_link_hist *h = &l->hist[seq & (WIN(l) - 1u)];
    return h->state != H_EMPTY && h->seq == seq ? h : NULL;
}

static void drain(it2n_link *l);

/* Record and send the answer to seq (no delivery of kept frames here, so
 * drain -> deliver -> answer has no cycle). */
static int answer(it2n_link *l, uint16_t seq, int code, const it2n_errinfo *detail)
{
    it2n_link_hist *h = hist_find(l, seq);
    if (h == NULL || h->state != H_WAITING)
        return IT2N_PROTO_ERR_SEQ;
    nack_plain(&h->answer, seq, code > 0 ? IT2N_ERR_INVAL : code);
    if (code < 0 && detail != NULL) {
        h->answer.i = detail->i;
        h->answer.j = detail->j;
        h->answer.fp = detail->fp;
        h->answer.ch = detail->ch;
        h->answer.value = detail->value;
        h->answer.lo = detail->lo;
        h->answer.hi = detail->hi;
    }
    h->state = H_ANSWERED;
    send_answer(l, &h->answer);
    return IT2N_OK;
}

int it2n_link_complete(it2n_link *l, uint16_t seq, int code, const it2n_errinfo *detail)
{
    int r = answer(l, seq, code, detail);
    if (r == IT2N_OK)
        drain(l); /* kept frames in order go on (none waits for an answer) */
    return r;
}

/* Can rx_next be delivered now? Not while the application still owes an
 * answer to the frame W before it (same history entry). */
static bool can_deliver(const it2n_link *l, uint16_t seq)
{
    return l->hist[seq & (WIN(l) - 1u)].state != H_WAITING;
}

/* Deliver frame seq = rx_next (message body p, len bytes). */
static void deliver(it2n_link *l, uint16_t seq, uint8_t type, const uint8_t *p, size_t len)
{
    it2n_link_hist *h = &l->hist[seq & (WIN(l) - 1u)];
    it2n_proto_errinfo info;
    it2n_msg m;
    uint8_t was;
    int r;

    h->seq = seq;
    h->state = H_WAITING;
    l->rx_next = (uint16_t)(seq + 1u);
    r = it2n_msg_unpack(type, p, len, &m, &info);
    if (r < 0) {
        /* Malformed message: answered by the link, never delivered. The
         * detail says where: lo = payload offset, value found, hi = limit. */
        l->stats.rx_bad_msg++;
        nack_plain(&h->answer, seq, r);
        h->answer.lo = info.offset;
        h->answer.value = info.value;
        h->answer.hi = info.limit;
        h->state = H_ANSWERED;
        send_answer(l, &h->answer);
        return;
    }
    l->stats.rx_delivered++;
    /* No delivery from inside the callback (an answer given there must not
     * run the next frame's callback before this one returns). */
    was = l->draining;
    l->draining = 1;
    r = l->cfg.on_rx(l->cfg.app, seq, &m);
    l->draining = was;
    if (r != IT2N_LINK_DEFER)
        (void)answer(l, seq, r, NULL);
    else if (h->state == H_WAITING && h->seq == seq)
        send_rcvd(l, seq); /* v1.2: the sender need not resend it */
}

/* Frame seq = rx_next comes W after one still awaiting the application's
 * answer (same history entry): its sender keeps more frames unanswered
 * than the window allows (docs/protocol.md 4.2 rule 2). Refused with NACK
 * BUSY, not delivered; `next` advances as for any NACK (4.3 rule 3). The
 * history entry stays the older frame's: a retransmission of this one is
 * recognised by it (refused_busy) and refused again. */
static void refuse_busy(it2n_link *l, uint16_t seq)
{
    it2n_msg_nack a;
    nack_plain(&a, seq, IT2N_PROTO_ERR_BUSY);
    l->rx_next = (uint16_t)(seq + 1u);
    l->stats.rx_busy++;
    send_answer(l, &a);
}

/* Was seq (behind rx_next) refused BUSY? Its history entry then still
 * holds the frame W before it, awaiting the application's answer. */
static bool refused_busy(const it2n_link *l, uint16_t seq)
{
    const it2n_link_hist *h = &l->hist[seq & (WIN(l) - 1u)];
    return (uint16_t)(l->rx_next - seq) - 1u < WIN(l) && h->state == H_WAITING && h->seq == (uint16_t)(seq - WIN(l));
}

/* Deliver kept frames that are now in order (one W after a frame still
 * awaiting its answer is refused BUSY instead). Not re-entered: callbacks
 * that answer at once come back through it2n_link_complete. */
static void drain(it2n_link *l)
{
#if IT2N_PROTO_RX_REORDER
    unsigned guard;
    if (l->draining)
        return;
    l->draining = 1;
    for (guard = 0; guard < W; guard++) {
        it2n_link_rxbuf *b = &l->rxbuf[l->rx_next & (WIN(l) - 1u)];
        if (!b->used || b->seq != l->rx_next)
            break;
        b->used = 0;
        if (!can_deliver(l, b->seq)) {
            refuse_busy(l, b->seq);
            continue;
        }
        deliver(l, b->seq, b->type, b->payload, b->len);
        l->draining = 1;
    }
    l->draining = 0;
#else
    (void)l;
#endif
}

/* Refuse frame fh (not delivered): NACK code, framed in its version and
 * after its session (v1.2), so that its sender, and only it, reads it. */
static void refuse_frame(it2n_link *l, const it2n_frame_hdr *fh, uint32_t tag, int code, int64_t value, int64_t hi)
{
    it2n_msg_nack a;
    nack_plain(&a, fh->seq, code);
    a.value = value;
    a.hi = hi;
    send_answer_vt(l, &a, fh->version, tag);
}

#if IT2N_PROTO_RX_REORDER
/* GAP: we miss rx_next and have just kept `have`. In v1.2 it names every
 * frame we hold beyond the gap (bit k: rx_next + 1 + k), so that the
 * sender resends only the missing ones (docs/protocol.md 4.3 rule 4). */
static void send_gap(it2n_link *l, uint16_t have)
{
    it2n_msg g;
    uint8_t gb[SESS + IT2N_GAP12_LEN];
    size_t off = l->rx_ver == V12 ? SESS : 0u;
    it2n_frame_hdr gh;
    unsigned k;
    int n;
    memset(&g, 0, sizeof g);
    g.type = IT2N_MSG_GAP;
    g.u.gap.seq = l->rx_next;
    g.u.gap.have = have;
    for (k = 1; l->rx_ver == V12 && k < WIN(l); k++) {
        const it2n_link_rxbuf *b = &l->rxbuf[(uint16_t)(l->rx_next + k) & (WIN(l) - 1u)];
        if (b->used && b->seq == (uint16_t)(l->rx_next + k))
            g.u.gap.held |= (uint64_t)1u << (k - 1u);
    }
    put_u32(gb, l->peer_session);
    n = it2n_msg_pack(&g, gb + off, sizeof gb - off, NULL);
    if (n <= 0)
        return;
    gh.version = l->rx_ver;
    gh.type = IT2N_MSG_GAP;
    gh.flags = 0;
    gh.seq = 0;
    gh.len = (uint16_t)((size_t)n + off);
    (void)frame_out(l, &gh, gb, gh.len);
    l->stats.tx_gaps++;
}
#endif

/* A new receive sequence at seq of session sess (history and kept frames
 * cleared). */
static void start_seq(it2n_link *l, uint16_t seq, uint32_t sess, uint8_t ver)
{
    l->rx_synced = 1;
    l->peer_session = sess;
    l->rx_ver = ver;
    l->rx_next = seq;
    memset(l->hist, 0, sizeof l->hist);
#if IT2N_PROTO_RX_REORDER
    {
        unsigned k;
        for (k = 0; k < W; k++)
            l->rxbuf[k].used = 0;
    }
#endif
}

/* A HELLO that would start a session is well-formed? Otherwise it is
 * NACKed with the parse detail (after session t) and changes nothing. */
static bool hello_ok(it2n_link *l, const it2n_frame_hdr *fh, uint32_t t, const uint8_t *p, size_t len)
{
    it2n_msg m;
    it2n_proto_errinfo info;
    int r = it2n_msg_unpack(fh->type, p, len, &m, &info);
    if (r >= 0)
        return true;
    l->stats.rx_bad_msg++;
    {
        it2n_msg_nack a;
        nack_plain(&a, fh->seq, r);
        a.lo = info.offset;
        a.value = info.value;
        a.hi = info.limit;
        send_answer_vt(l, &a, fh->version, t);
    }
    return false;
}

/* v1.2: may a frame of session t go on to the sequence rules (true), or
 * was it refused (false)? docs/protocol.md 4.1 and 4.3 rule 0. */
static bool v12_admit(it2n_link *l, const it2n_frame_hdr *fh, uint32_t t, const uint8_t *p, size_t len, uint32_t now)
{
    bool syn = (fh->flags & IT2N_FLAG_SYN) != 0u;
    if (SERVER(l)) {
        if (t == 0u) {
            /* Session 0 asks for a session: only a HELLO, with SYN. It
             * always starts a new sequence (a rebooted instrument's first
             * frame is never taken for its previous life's). */
            if (!syn || fh->type != IT2N_MSG_HELLO)
                goto foreign;
            if (!hello_ok(l, fh, t, p, len))
                return false; /* malformed: nothing changes */
            offer(l);
            l->rx_synced = 0; /* a new peer: limits reset until its HELLO */
            return true;
        }
        if (l->rx_synced && l->rx_ver == V12 && t == l->peer_session)
            return true; /* the current session */
        if (syn && offered(l, t)) {
            /* The peer takes up a session we handed out. */
            establish(l, t, now);
            start_seq(l, fh->seq, t, V12);
            l->stats.rx_sessions++;
            return true;
        }
    } else if (CLIENT(l)) {
        if (l->tag == 0u) {
            if (syn && t != 0u && fh->type == IT2N_MSG_HELLO) {
                /* The server's HELLO: our session from now on. */
                if (!hello_ok(l, fh, t, p, len))
                    return false;
                adopt(l, t, now);
                start_seq(l, fh->seq, t, V12);
                l->stats.rx_sessions++;
                l->peer_window = IT2N_PROTO_WINDOW_MIN;
                l->peer_max_payload = IT2N_PROTO_MAX_PAYLOAD;
                return true;
            }
        } else if (t == l->tag) {
            if (syn && (!l->rx_synced || l->peer_session != t))
                start_seq(l, fh->seq, t, V12); /* a sequence of ours */
            return true;
        }
    }
foreign:
    /* Not a session of ours: a previous life's frame (a rebooted peer's,
     * or one from before we restarted). Never delivered; its sender, if it
     * is still there, asks for a new session (rule 0). */
    l->stats.rx_foreign++;
    refuse_frame(l, fh, t, IT2N_PROTO_ERR_SESSION, (int64_t)t, 0);
    return false;
}

static void on_reliable(it2n_link *l, const it2n_frame_hdr *fh, const uint8_t *p, uint32_t now)
{
    it2n_link_hist *h;
    it2n_msg_nack a;
    size_t len = fh->len;
    uint16_t ahead;
    uint32_t sess = 0;

    if (fh->version == V12 || (fh->flags & IT2N_FLAG_SYN)) {
        if (len < SESS) { /* no session id: cannot start a sequence */
            l->stats.rx_bad_msg++;
            refuse_frame(l, fh, 0u, IT2N_PROTO_ERR_PAYLOAD, (int64_t)len, SESS);
            return;
        }
        sess = get_u32(p);
        p += SESS;
        len -= SESS;
    }
    if (fh->version == V12) {
        if (!v12_admit(l, fh, sess, p, len, now))
            return;
    } else if (l->rx_ver == V12 && !(fh->flags & IT2N_FLAG_SYN)) {
        /* a v1.1 frame is no part of a v1.2 sequence */
        l->stats.rx_nosync++;
        refuse_frame(l, fh, 0u, IT2N_PROTO_ERR_NOSYNC, 0, 0);
        return;
    }
    if (fh->flags & IT2N_FLAG_SYN) {
        /* A SYN frame is a retransmission only if it belongs to the
         * current peer session and its number is in the history; anything
         * else starts a new sequence (a restarted peer has a new id). */
        if (l->rx_synced && sess == l->peer_session && sess != 0u && fh->version == l->rx_ver &&
            hist_find(l, fh->seq) == NULL && (uint16_t)(l->rx_next - fh->seq) - 1u < 0x7FFFu) {
            /* This session's SYN from behind `next` and out of the
             * history: a stale copy (a sender never restarts a sequence
             * behind what it sent); not a new sequence. */
            l->stats.rx_ahead++;
            return;
        }
        /* Session id 0 is "no id": every SYN frame of it starts a new
         * sequence (never mistaken for an old session's frame; a SYN copy
         * whose ACK was lost is delivered again — it travels alone). */
        if (!l->rx_synced || sess != l->peer_session || sess == 0u || fh->version != l->rx_ver ||
            hist_find(l, fh->seq) == NULL) {
            if (!l->rx_synced || sess != l->peer_session || fh->version != l->rx_ver) {
                /* a new peer session: its limits are unknown until its
                 * HELLO (delivered next, if this frame is one) */
                l->stats.rx_sessions++;
                l->peer_window = IT2N_PROTO_WINDOW_MIN;
                l->peer_max_payload = IT2N_PROTO_MAX_PAYLOAD;
            }
            if (fh->version != V12 && l->ver == V12 && SERVER(l)) {
                /* a v1.1 peer now: what we had for a v1.2 one is gone */
                l->ver = V11;
                l->tag = 0;
                drop_foreign(l, V11, 0u);
                l->tx_synced = 0;
            }
            start_seq(l, fh->seq, sess, fh->version);
        }
    } else if (!l->rx_synced) {
        l->stats.rx_nosync++;
        refuse_frame(l, fh, sess, IT2N_PROTO_ERR_NOSYNC, 0, 0);
        return;
    }
    if (fh->seq == l->rx_next) {
        if (can_deliver(l, fh->seq))
            deliver(l, fh->seq, fh->type, p, len);
        else
            refuse_busy(l, fh->seq); /* the peer broke its window */
        drain(l);
        return;
    }
    h = hist_find(l, fh->seq);
    if (h != NULL && (uint16_t)(l->rx_next - fh->seq) <= WIN(l)) {
        l->stats.rx_dup++;
        if (h->state == H_ANSWERED)
            send_answer(l, &h->answer); /* our answer was lost: repeat it */
        else
            send_rcvd(l, fh->seq); /* v1.2: still pending (RCVD lost) */
        return;
    }
    ahead = (uint16_t)(fh->seq - l->rx_next);
    if (refused_busy(l, fh->seq)) {
        /* a retransmission of a frame refused BUSY (our NACK was lost) */
        nack_plain(&a, fh->seq, IT2N_PROTO_ERR_BUSY);
        l->stats.rx_busy++;
        send_answer(l, &a);
        return;
    }
#if IT2N_PROTO_RX_REORDER
    if (ahead < WIN(l) && len <= IT2N_PROTO_MAX_PAYLOAD) {
        /* Ahead of a gap: keep it. */
        it2n_link_rxbuf *b = &l->rxbuf[fh->seq & (WIN(l) - 1u)];
        bool again = b->used && b->seq == fh->seq;
        if (!again || (fh->flags & IT2N_FLAG_RETX)) {
            /* A retransmission of a frame kept already: the sender has not
             * got our GAP (or its answer to it was lost): say it again. */
            if (!again) {
                b->used = 1;
                b->seq = fh->seq;
                b->type = fh->type;
                b->len = (uint16_t)len;
                memcpy(b->payload, p, len);
                l->stats.rx_buffered++;
            }
            if (ahead > 0u &&
                !(l->rxbuf[l->rx_next & (WIN(l) - 1u)].used && l->rxbuf[l->rx_next & (WIN(l) - 1u)].seq == l->rx_next))
                send_gap(l, fh->seq); /* tell the sender which frame we miss */
        }
        return;
    }
#endif
    if (ahead < WIN(l)) {
        /* Kept nowhere (IT2N_PROTO_RX_REORDER 0): the sender retries. */
        l->stats.rx_ahead++;
        return;
    }
    /* Neither answered recently nor within the window ahead: a stale copy
     * (its sender no longer has it in flight and ignores this answer), or
     * the sender's sequence is not ours (we synced on a stale copy of an
     * old SYN frame): NOSYNC makes such a sender start again with SYN
     * (docs/protocol.md 4.3 rule 6). Never silent: silence would leave a
     * sender retrying a frame we drop until it gives up. */
    if (ahead >= 0x8000u)
        l->stats.rx_stale++; /* behind `next` and the history */
    else
        l->stats.rx_ahead++; /* beyond the window */
    nack_plain(&a, fh->seq, IT2N_PROTO_ERR_NOSYNC);
    send_answer(l, &a);
}

/* Versions this link speaks: v1.1 links 2, v1.2 clients 3, servers both. */
static uint8_t ver_lo(const it2n_link *l)
{
    return CLIENT(l) ? (uint8_t)V12 : (uint8_t)V11;
}

static uint8_t ver_hi(const it2n_link *l)
{
    return CLIENT(l) || SERVER(l) ? (uint8_t)V12 : (uint8_t)V11;
}

static void on_frame(it2n_link *l, int r, const it2n_frame_hdr *fh, const uint8_t *p, uint32_t now)
{
    size_t len = fh->len;
    uint32_t tag = 0;
    if (r == 1 && (fh->version < ver_lo(l) || fh->version > ver_hi(l)))
        r = IT2N_PROTO_ERR_VERSION; /* a version the decoder knows, not we */
    if ((r == 1 || r == IT2N_PROTO_ERR_VERSION) && fh->version == V12 && !(fh->flags & IT2N_FLAG_REL)) {
        /* v1.2 answers start with the session of the frame answered */
        if (len < SESS) {
            l->stats.rx_bad_msg++;
            return;
        }
        tag = get_u32(p);
        p += SESS;
        len -= SESS;
    }
    if (r == IT2N_PROTO_ERR_VERSION) {
        /* ACK and NACK have one layout in every version: read an older
         * peer's answers (its VERSION refusal, notably). */
        if (fh->type == IT2N_MSG_ACK || fh->type == IT2N_MSG_NACK) {
            it2n_msg m;
            if (fh->version >= 1u && (fh->flags & IT2N_FLAG_REL) == 0u &&
                it2n_msg_unpack(fh->type, p, len, &m, NULL) == IT2N_OK)
                on_answer(l, &m, fh->version, tag, now);
            return;
        }
        /* Intact reliable frame of another version: tell the sender which
         * versions we speak (NACK value/lo/hi), framed in its version when
         * it is older so that it can read the refusal. */
        if (fh->flags & IT2N_FLAG_REL) {
            it2n_msg_nack a;
            nack_plain(&a, fh->seq, IT2N_PROTO_ERR_VERSION);
            a.value = fh->version;
            a.lo = ver_lo(l);
            a.hi = ver_hi(l);
            send_answer_v(l, &a, fh->version >= 1u && fh->version < ver_hi(l) ? fh->version : ver_hi(l));
        }
        return;
    }
    if (r != 1)
        return; /* damaged: counted by the decoder, sender retransmits */
    if (fh->type == IT2N_MSG_ACK || fh->type == IT2N_MSG_NACK || fh->type == IT2N_MSG_GAP ||
        fh->type == IT2N_MSG_RCVD) {
        it2n_msg m;
        if (it2n_msg_unpack(fh->type, p, len, &m, NULL) != IT2N_OK || (fh->flags & IT2N_FLAG_REL) != 0u ||
            (m.type == IT2N_MSG_ACK && fh->version != V12 && len != 2u))
            l->stats.rx_bad_msg++; /* answers are never REL; v1.1 ACK: 2 bytes */
        else if (m.type == IT2N_MSG_RCVD) {
            /* v1.2 only, about our frames of that session only */
            if (fh->version != V12)
                l->stats.rx_bad_msg++;
            else if (l->ver == V12 && tag == l->tag)
                on_rcvd(l, m.u.rcvd.seq, now);
        } else if (m.type == IT2N_MSG_GAP) {
            /* about our frames of that session only; v1.2 GAPs name the
             * frames held (12 bytes), v1.1 ones only `have` (4 bytes) */
            if ((fh->version == V12) != (len == IT2N_GAP12_LEN) || (fh->version == V12 && m.u.gap.held == 0u))
                l->stats.rx_bad_msg++;
            else if (fh->version == l->ver && (l->ver != V12 || tag == l->tag))
                on_gap(l, m.u.gap.seq, m.u.gap.have, m.u.gap.held, now);
        } else
            on_answer(l, &m, fh->version, tag, now);
        return;
    }
    if (!(fh->flags & IT2N_FLAG_REL)) {
        l->stats.rx_bad_msg++; /* every other message must be reliable */
        return;
    }
    on_reliable(l, fh, p, now);
}

int it2n_link_input(it2n_link *l, const uint8_t *data, size_t len, uint32_t now)
{
    if (len > 0u) {
        l->rx_last = now;
        l->rx_heard = 1;
    }
    l->clock = now;
    while (len > 0u) {
        it2n_frame_hdr fh;
        const uint8_t *p = NULL;
        size_t used = 0;
        int r = it2n_frame_decode(&l->dec, data, len, &used, &fh, &p);
        if (r != 0)
            on_frame(l, r, &fh, p, now);
        data += used;
        len -= used;
    }
    if (l->rx_heard && l->rx_last == now)
        probe_heard(l, now);
    return IT2N_OK;
}

int it2n_link_pump(it2n_link *l, uint32_t now)
{
    uint8_t buf[64];
    unsigned k;

    if (l->cfg.in == NULL || l->cfg.in->read == NULL)
        return IT2N_PROTO_ERR_STREAM;
    /* Bounded: at most two maximal frames per call, then let poll run. */
    for (k = 0; k < 2u * IT2N_FRAME_MAX_WIRE / sizeof buf + 1u; k++) {
        int n = l->cfg.in->read(l->cfg.in, buf, sizeof buf);
        if (n < 0)
            return IT2N_PROTO_ERR_STREAM;
        if (n == 0)
            break;
        (void)it2n_link_input(l, buf, (size_t)n > sizeof buf ? sizeof buf : (size_t)n, now);
    }
    return IT2N_OK;
}
