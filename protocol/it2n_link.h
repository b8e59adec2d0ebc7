/*
 * it2n — reliable transport over the framing layer.
 *
 * A state machine driven by the caller: it never reads a clock or sleeps;
 * every entry point takes `now` in milliseconds (any monotonic origin,
 * wrapping at 2^32). Each direction has its own 16-bit sequence space.
 *
 * Window: this side's own window (cfg.window, 0 = IT2N_PROTO_WINDOW, the
 * build's maximum) is what it announces in HELLO (it2n_link_window) and
 * sizes what the receiver keeps. The sender keeps up to the protocol
 * minimum IT2N_PROTO_WINDOW_MIN (4) frames in flight until the peer's
 * HELLO is applied (it2n_link_set_peer), then min(own, announced).
 *
 * Sender: up to that many reliable frames in flight, each kept in
 * the context until ACKed or NACKed and retransmitted after the RTO, which
 * doubles on every retransmission up to rto_max_ms; the RTO itself follows
 * the measured round trip (SRTT + 4 RTTVAR, RFC 6298 with Karn's rule),
 * never below rto_ms nor above rto_max_ms, and into a silence of the peer
 * only the oldest frame is resent (one probe); after max_tries
 * transmissions (0 = never) the frame is given up (IT2N_PROTO_ERR_TIMEOUT).
 * The first frame of a sequence carries IT2N_FLAG_SYN and the sender's
 * session id, and travels alone.
 *
 * Receiver: delivers reliable frames once and in order. The application
 * answers each delivery at once (return 0 or a negative NACK code from the
 * callback) or later (return IT2N_LINK_DEFER and call it2n_link_complete,
 * e.g. after fsync). A retransmission of a frame already answered is
 * re-answered with the same ACK/NACK and NOT delivered again; one still
 * awaiting its answer is ignored. A SYN frame is a retransmission only when
 * it carries the current peer session id and its number is in the
 * history: a restarted peer (new session id) always starts a new sequence.
 * Frames ahead of the expected sequence number (within the window) are
 * kept and delivered once the gap is filled (IT2N_PROTO_RX_REORDER).
 * A frame W after one still awaiting the application's answer (its sender
 * keeps more unanswered than the window) is refused NACK BUSY, not
 * delivered (docs/protocol.md 4.3 rule 3).
 *
 * Sessions (docs/protocol.md 4.1): a v1.1 link's SYN frames carry its own
 * cfg.session. In v1.2 the server hands out the session id: a client
 * (cfg.version = IT2N_PROTO_VERSION_12) sends HELLO with session 0 as its
 * first frame, takes the id from the server's HELLO, and every frame both
 * ways carries it; frames of another session are answered NACK SESSION and
 * never delivered. A server (cfg.new_session set) serves v1.2 and v1.1
 * peers alike, whichever a frame's version says.
 *
 * Selective acknowledgement (docs/protocol.md 4.2 rule 4): frames a GAP
 * names as held (v1.2: all of them, v1.1: `have`) are not resent on a
 * timer while an older frame is missing; a v1.2 ACK also names the frames
 * ACKed before it; a v1.2 receiver whose application defers an answer
 * sends RCVD, after which the sender waits twice the deferral it has seen
 * (at least 2 RTO) before resending. With cfg.baud a new frame is written
 * only while at most two maximum frames wait on the line (the rest are
 * written by it2n_link_poll), so a retransmission never queues behind a
 * window of new frames.
 *
 * Contexts are plain structs in caller memory; any number may coexist.
 * The callbacks may call it2n_link_send / it2n_link_complete on the same
 * context.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#ifndef IT2N_LINK_H
#define IT2N_LINK_H

#include "it2n_msg.h"

/* Callback return: the application will answer with it2n_link_complete. */
#define IT2N_LINK_DEFER 1

/*
 * A reliable message arrived (already unpacked and range-checked). Return 0
 * to ACK now, a negative error code to NACK now (no detail), or
 * IT2N_LINK_DEFER.
 */
typedef int (*it2n_link_rx_fn)(void *app, uint16_t seq, const it2n_msg *msg);

/*
 * A sent reliable message is finished: code 0 = ACKed, negative = NACKed
 * (nack points at the peer's detail) or IT2N_PROTO_ERR_TIMEOUT (nack NULL).
 */
typedef void (*it2n_link_done_fn)(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack);

typedef struct it2n_link_cfg {
    it2n_ostream *out;         /* where frames go (required)          */
    it2n_istream *in;          /* for it2n_link_pump (may be NULL)    */
    it2n_link_rx_fn on_rx;     /* required                           */
    it2n_link_done_fn on_done; /* may be NULL                      */
    void *app;                 /* passed to the callbacks             */
    uint32_t rto_ms;           /* first retransmission timeout, >= 1;
                               the minimum: the RTO adapts to the
                               round trips measured above it       */
    uint8_t max_tries;         /* transmissions before giving up,
                               0 = retry until the app gives up    */
    uint16_t first_seq;        /* initial sequence number (random)    */
    /* v1.1 (added at the end: older positional initialisers still
     * compile and get 0 = defaults). */
    uint32_t session;    /* this session's id: must differ from
                               every earlier session of this sender
                               (random, or a persisted boot counter);
                               0 = none: then a retransmitted SYN frame
                               may be delivered twice (docs/protocol.md
                               4.3 rule 1)                           */
    uint32_t rto_max_ms; /* backoff cap; 0 = 8 x rto_ms          */
    uint8_t window;      /* own window: frames in flight we accept
                               and send at most; a power of two within
                               4..IT2N_PROTO_WINDOW, 0 = IT2N_PROTO_WINDOW */
    uint32_t baud;       /* line rate (bits/s, 10 bits a byte) or
                               0 = unknown. When known, the RTO of a
                               frame counts from when its last byte
                               has left the line (estimated from the
                               bytes written before it), and a due
                               retransmission waits while the peer's
                               bytes keep arriving (its answer may be
                               queued behind them), at most the time
                               IT2N_PROTO_WINDOW maximum frames take
                               (docs/protocol.md 4.2 rule 3)          */
    /* v1.2 (docs/protocol.md 4.1): the server hands out session ids. */
    uint8_t version;                    /* 0 or IT2N_PROTO_VERSION: v1.1 (session
                               above); IT2N_PROTO_VERSION_12: v1.2
                               client: the first message must be HELLO,
                               sent with session 0; the server's HELLO
                               gives the session every later frame
                               carries (cfg.session unused). The link
                               re-sends that HELLO by itself whenever
                               the server does not know the session
                               (it restarted): NACK SESSION          */
    uint32_t (*new_session)(void *app); /* server: serve v1.2 peers too
                               (v1.1 ones as before): a fresh non-zero
                               session id for each v1.2 HELLO, e.g.
                               from getrandom(); NULL = v1.1 only     */
} it2n_link_cfg;

/* Largest HELLO a v1.2 client keeps to re-send (the message is 28 bytes). */
#define IT2N_LINK_HELLO_MAX 28

typedef struct it2n_link_stats {
    uint32_t tx_frames, tx_retx, tx_acked, tx_nacked, tx_timeouts;
    uint32_t rx_delivered, rx_dup, rx_ahead, rx_nosync, rx_bad_msg;
    uint32_t rx_acks, rx_stale_acks;
    uint32_t rx_buffered;     /* frames kept ahead of a gap          */
    uint32_t rx_sessions;     /* new peer sessions seen              */
    uint32_t tx_dropped;      /* frames dropped by it2n_link_drop_tx */
    uint32_t tx_gaps;         /* GAPs sent (we hold frames past a gap) */
    uint32_t tx_fast_retx;    /* retransmissions on a peer's GAP      */
    uint32_t rx_stale;        /* behind next and out of the history:
                               answered NOSYNC                   */
    uint32_t tx_resyncs;      /* restarts with SYN: the peer's NOSYNC,
                               or its GAP for a frame we count as
                               answered                          */
    uint32_t rx_foreign;      /* v1.2: frames of a session not ours:
                               answered NACK SESSION, not delivered */
    uint32_t tx_hellos;       /* v1.2 client: HELLOs sent for a session
                               (first and re-sent ones, not retries) */
    uint32_t tx_held;         /* our frames a GAP named as held (each
                               marked once): not resent on timeout  */
    uint32_t tx_rcvd;         /* v1.2 RCVDs sent (answer deferred)    */
    uint32_t rx_rcvd;         /* our frames a RCVD named (each once)  */
    uint32_t rx_acks_implied; /* our frames ended by a v1.2 ACK of a
                               later one (their own ACK was lost)   */
    uint32_t rx_busy;         /* frames refused NACK BUSY: W after one
                               still awaiting our application's
                               answer (the peer broke its window)   */
    uint32_t tx_stall_waits;  /* timeouts not resent at once: the peer
                               was silent after newer frames it would
                               have answered (a stall, 4.2 rule 3)  */
} it2n_link_stats;

/* One sender slot: a reliable frame in flight. The message starts at
 * buf[IT2N_FRAME_SESSION_SIZE]; the room before it takes the session id
 * when the frame is sent with SYN. */
typedef struct it2n_link_slot {
    uint8_t used, tries, type, flags;
    uint16_t seq, len;
    uint32_t deadline, first, last; /* next try, first and last sent */
    uint32_t gone;                  /* when the last copy left the line (estimated)   */
    uint8_t tmo;                    /* retransmissions on timeout: the backoff exponent
                       (fast retransmissions do not back off)          */
    uint8_t ver;                    /* wire version it is framed in                     */
    uint8_t held;                   /* 1: the receiver holds it beyond a gap (its GAP
                       said so): no retransmission on timeout while an
                       older frame is missing; 2: it was delivered, the
                       answer is pending (RCVD, v1.2): no retransmission
                       before rto_max_ms (docs/protocol.md 4.2 rule 4) */
    uint32_t tag;                   /* v1.2: the session it belongs to                  */
    uint32_t rcvd;                  /* when its RCVD came (held 2)                      */
    uint8_t probe_wait;             /* 1: its timeout fell due while an older frame's
                       retransmission on timeout was unanswered and the
                       peer silent: it waits (one probe into silence);
                       2: it fell due in a silence of the peer after
                       newer frames: a stall, it waits once (rule 3)    */
    uint8_t nosample;               /* 1: an older frame was retransmitted while this
                       one was in flight, so its answer may have waited
                       for that one: no round-trip sample (Karn)         */
    uint8_t buf[IT2N_FRAME_MAX_LEN];
} it2n_link_slot;

/* v1.2 client: the HELLO asking for a session (sent with session 0). */
typedef struct it2n_link_hello {
    uint8_t used;  /* in flight: no session yet                        */
    uint8_t acked; /* ACKed; the server's HELLO (the session) is due   */
    uint8_t tries, len;
    uint16_t seq;
    uint32_t deadline, first; /* next try; when first asked          */
    uint8_t buf[IT2N_FRAME_SESSION_SIZE + IT2N_LINK_HELLO_MAX];
} it2n_link_hello;

/* One receiver reorder entry: a frame ahead of the expected one. */
typedef struct it2n_link_rxbuf {
    uint8_t used, type;
    uint16_t seq, len;
    uint8_t payload[IT2N_PROTO_MAX_PAYLOAD];
} it2n_link_rxbuf;

/* One receiver history entry: answer to a recent reliable frame. */
typedef struct it2n_link_hist {
    uint8_t state; /* 0 empty, 1 awaiting the app, 2 answered */
    uint16_t seq;
    it2n_msg_nack answer; /* code 0 = ACK */
} it2n_link_hist;

typedef struct it2n_link {
    it2n_link_cfg cfg;
    /* sender */
    uint16_t tx_next;
    uint8_t tx_synced;         /* peer accepted our SYN frame */
    uint8_t win;               /* own window (cfg.window resolved)   */
    uint8_t peer_window;       /* frames in flight the peer accepts  */
    uint16_t peer_max_payload; /* largest message the peer accepts   */
    it2n_link_slot slot[IT2N_PROTO_WINDOW];
    /* receiver */
    uint16_t rx_next;
    uint8_t rx_synced;
    uint8_t draining;
    uint32_t peer_session; /* session id of the current sequence */
    it2n_link_hist hist[IT2N_PROTO_WINDOW];
#if IT2N_PROTO_RX_REORDER
    it2n_link_rxbuf rxbuf[IT2N_PROTO_WINDOW];
#endif
    it2n_frame_decoder dec;
    it2n_link_stats stats;
    /* v1.2 (docs/protocol.md 4.1) */
    uint8_t ver;           /* wire version of our new frames      */
    uint8_t rx_ver;        /* ... of the current receive sequence */
    uint32_t tag;          /* the session: handed out by the server
                                  (0 = none yet); our frames carry it */
    uint32_t offer[4];     /* server: handed out, not taken up yet */
    it2n_link_hello hello; /* client: HELLO kept for re-sending   */
    /* line clock (cfg.baud > 0): when the bytes written so far have left
     * (line_free, plus line_frac / baud ms), the latest `now` seen, and
     * when the peer's bytes last arrived */
    uint32_t line_free, line_frac, clock, rx_last;
    uint8_t rx_heard;  /* rx_last is set */
    uint32_t defer_ms; /* how long the peer's deferred answers take after
                          their RCVD (the largest lately, decaying): a
                          frame with a RCVD is resent after twice that,
                          at least 2 RTO (docs/protocol.md 4.2 rule 4) */
    /* Adaptive RTO (docs/protocol.md 4.2 rule 3, RFC 6298 with Karn's
     * rule): smoothed round trip x 8 and its mean deviation x 4, in ms,
     * from answers to frames sent once; rto is the current first timeout,
     * within cfg.rto_ms .. cfg.rto_max_ms. */
    uint32_t srtt8, rttvar4, rto;
    uint8_t rtt_valid; /* a sample was taken */
} it2n_link;

/*
 * The default first retransmission timeout for a line of `baud` bits/s
 * (0 = unknown: 100 ms), counted from when the frame has left the line
 * (cfg.baud set): 20 ms for the peer's turnaround plus the time one
 * maximum frame takes at the baud rate (32 ms at 921 600, 111 ms at
 * 115 200, 1110 ms at 9600; docs/protocol.md 4.2 rule 3).
 */
uint32_t it2n_link_rto_default(uint32_t baud);
/* The struct above depends on IT2N_PROTO_WINDOW, IT2N_PROTO_MAX_PAYLOAD and
 * IT2N_PROTO_RX_REORDER: it2n_link_init's link-time name carries them (see
 * IT2N_PROTO_ABI in it2n_proto.h), so a program compiled with other values
 * than the library fails to link. Callers just write it2n_link_init. */
#define it2n_link_init IT2N_PROTO_ABI(it2n_link_init)

/* Initialise a link context from cfg (copied). Returns IT2N_OK or
 * IT2N_ERR_INVAL for a missing callback/stream, zero rto/tries, or a
 * window that is not a power of two within 4..IT2N_PROTO_WINDOW. */
int it2n_link_init(it2n_link *l, const it2n_link_cfg *cfg);

/* This side's own window (what to announce in HELLO `window`). */
uint8_t it2n_link_window(const it2n_link *l);

/* Frames in flight the sender may keep now: min(own window, the peer's
 * announced window), IT2N_PROTO_WINDOW_MIN until the peer's HELLO. */
uint8_t it2n_link_send_window(const it2n_link *l);

/*
 * Queue and transmit a reliable message. Returns its sequence number
 * (0..65535), IT2N_PROTO_ERR_BUSY when the window is full (call poll/input
 * and retry), IT2N_PROTO_ERR_NOSPACE when the packed message is larger
 * than the peer's announced max_payload, or a pack error (message
 * unchanged, nothing sent). A stream error is not returned: the frame
 * stays queued for retransmission.
 */
int32_t it2n_link_send(it2n_link *l, const it2n_msg *msg, uint32_t now);

/* Frames in flight (0 = everything sent has been answered). */
unsigned it2n_link_pending(const it2n_link *l);

/* True when it2n_link_send would not return IT2N_PROTO_ERR_BUSY. */
bool it2n_link_can_send(const it2n_link *l);

/*
 * Feed received bytes (any chunking). Handles ACK/NACK, delivers messages,
 * answers bad frames. Returns IT2N_OK or IT2N_PROTO_ERR_STREAM.
 */
int it2n_link_input(it2n_link *l, const uint8_t *data, size_t len, uint32_t now);

/* Read everything available from cfg.in and feed it. Returns IT2N_OK, or
 * IT2N_PROTO_ERR_STREAM when the stream failed or ended. */
int it2n_link_pump(it2n_link *l, uint32_t now);

/* Retransmit what is due and time out what is exhausted. */
int it2n_link_poll(it2n_link *l, uint32_t now);

/* Milliseconds until the next retransmission is due (0 = now), or
 * UINT32_MAX when nothing is in flight. For the caller's poll timeout. */
uint32_t it2n_link_next_timeout(const it2n_link *l, uint32_t now);

/*
 * Answer a delivery that returned IT2N_LINK_DEFER: code 0 sends ACK, a
 * negative code sends NACK with detail (may be NULL). Returns IT2N_OK or
 * IT2N_PROTO_ERR_SEQ when seq is not awaiting an answer.
 */
int it2n_link_complete(it2n_link *l, uint16_t seq, int code, const it2n_errinfo *detail);

/*
 * Apply the limits the peer announced in its HELLO: at most `window`
 * frames in flight (1..255, clamped to our own window; 0 = unchanged) and
 * no message larger than `max_payload` bytes (0 = unchanged). Until called
 * (and again from each new peer session on): IT2N_PROTO_WINDOW_MIN (4)
 * frames and IT2N_PROTO_MAX_PAYLOAD.
 */
void it2n_link_set_peer(it2n_link *l, uint8_t window, uint16_t max_payload);

/* The current session: v1.2 the id the server handed out (0 = none
 * yet), v1.1 the peer's session id of the current sequence. */
uint32_t it2n_link_session(const it2n_link *l);

/* The current first retransmission timeout (ms): the configured rto_ms
 * until round trips are measured, then SRTT + 4 RTTVAR within rto_ms ..
 * rto_max_ms (docs/protocol.md 4.2 rule 3). */
uint32_t it2n_link_rto(const it2n_link *l);

/* Largest message payload it2n_link_send accepts now (peer's limit). */
uint16_t it2n_link_max_payload(const it2n_link *l);

/*
 * Milliseconds the oldest frame in flight has waited for its answer
 * (0 when nothing is in flight): for declaring a silent peer down.
 */
uint32_t it2n_link_stalled_ms(const it2n_link *l, uint32_t now);

/*
 * Drop every frame in flight (the peer is declared down): each is reported
 * through on_done with IT2N_PROTO_ERR_DOWN, and the next frame starts a
 * new sequence with SYN. Returns the number of frames dropped.
 */
unsigned it2n_link_drop_tx(it2n_link *l);

#endif /* IT2N_LINK_H */
