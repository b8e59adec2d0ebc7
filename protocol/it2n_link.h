/*
 * it2n — reliable transport over the framing layer.
 *
 * A state machine driven by the caller: it never reads a clock or sleeps;
 * every entry point takes `now` in milliseconds (any monotonic origin,
 * wrapping at 2^32). Each direction has its own 16-bit sequence space.
 *
 * Sender: up to IT2N_PROTO_WINDOW reliable frames in flight, each kept in
 * the context until ACKed or NACKed and retransmitted after rto_ms; after
 * max_tries transmissions the frame is given up (IT2N_PROTO_ERR_TIMEOUT).
 * The first frame of a sequence carries IT2N_FLAG_SYN and travels alone.
 *
 * Receiver: delivers reliable frames once and in order. The application
 * answers each delivery at once (return 0 or a negative NACK code from the
 * callback) or later (return IT2N_LINK_DEFER and call it2n_link_complete,
 * e.g. after fsync). A retransmission of a frame already answered is
 * re-answered with the same ACK/NACK and NOT delivered again; one still
 * awaiting its answer is ignored. Frames ahead of the expected sequence
 * number are dropped (the sender retransmits them).
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
typedef void (*it2n_link_done_fn)(void *app, uint16_t seq, uint8_t type,
                                  int code, const it2n_msg_nack *nack);

typedef struct it2n_link_cfg {
    it2n_ostream *out;      /* where frames go (required)          */
    it2n_istream *in;       /* for it2n_link_pump (may be NULL)    */
    it2n_link_rx_fn on_rx;  /* required                           */
    it2n_link_done_fn on_done; /* may be NULL                      */
    void *app;              /* passed to the callbacks             */
    uint32_t rto_ms;        /* retransmission timeout, >= 1        */
    uint8_t max_tries;      /* transmissions before giving up, >=1 */
    uint16_t first_seq;     /* initial sequence number             */
} it2n_link_cfg;

typedef struct it2n_link_stats {
    uint32_t tx_frames, tx_retx, tx_acked, tx_nacked, tx_timeouts;
    uint32_t rx_delivered, rx_dup, rx_ahead, rx_nosync, rx_bad_msg;
    uint32_t rx_acks, rx_stale_acks;
} it2n_link_stats;

/* One sender slot: a reliable frame in flight. */
typedef struct it2n_link_slot {
    uint8_t used, tries, type, flags;
    uint16_t seq, len;
    uint32_t deadline;
    uint8_t payload[IT2N_PROTO_MAX_PAYLOAD];
} it2n_link_slot;

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
    uint8_t tx_synced; /* peer accepted our SYN frame */
    it2n_link_slot slot[IT2N_PROTO_WINDOW];
    /* receiver */
    uint16_t rx_next;
    uint8_t rx_synced;
    it2n_link_hist hist[IT2N_PROTO_WINDOW];
    it2n_frame_decoder dec;
    it2n_link_stats stats;
} it2n_link;

/* Initialise a link context from cfg (copied). Returns IT2N_OK or
 * IT2N_ERR_INVAL for a missing callback/stream or zero rto/tries. */
int it2n_link_init(it2n_link *l, const it2n_link_cfg *cfg);

/*
 * Queue and transmit a reliable message. Returns its sequence number
 * (0..65535), IT2N_PROTO_ERR_BUSY when the window is full (call poll/input
 * and retry), or a pack error (message unchanged, nothing sent). A stream
 * error is not returned: the frame stays queued for retransmission.
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
int it2n_link_input(it2n_link *l, const uint8_t *data, size_t len,
                    uint32_t now);

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
int it2n_link_complete(it2n_link *l, uint16_t seq, int code,
                       const it2n_errinfo *detail);

#endif /* IT2N_LINK_H */
