/*
 * it2n — instrument API: the few calls a firmware needs to upload grid
 * points to it2nd over a serial line and ask it questions (protocol v1.2,
 * docs/instrument.md has a worked example).
 *
 *   it2n_inst_open      start a session (HELLO; the daemon hands out its id)
 *   it2n_inst_configure start (or restart) a model: degrees n x m, flags
 *   it2n_inst_configure_bspline  ... a B-spline model, up to 256 x 256
 *                       points (v1.3 CONFIGURE; it2nd 1.3 or later)
 *   it2n_inst_put       one footprint of one grid point (batched for you)
 *   it2n_inst_put_fine  ... with memberships in Q30 (v1.3 PUT FINE)
 *   it2n_inst_commit    send what is batched, then COMMIT (solve)
 *   it2n_inst_query     evaluate the daemon's model at (u, w)
 *   it2n_inst_sync      wait until everything sent is acknowledged
 *   it2n_inst_feed      hand over received bytes (from the UART)
 *   it2n_inst_poll      retransmit what is due (call it often)
 *   it2n_inst_resync    start a new sequence (the peer was lost)
 *
 * You provide two callbacks: bytes out (write them to the UART) and the
 * time in milliseconds. Received bytes come either from a third callback
 * (read, polled: every call then waits for its answer, up to timeout_ms,
 * calling idle between polls) or from you, through it2n_inst_feed (from a
 * receive interrupt's buffer; calls then return IT2N_PROTO_ERR_BUSY when
 * the send window is full instead of waiting).
 *
 * Same rules as the rest of protocol/: C99 freestanding, no heap, no
 * global state; the context (about 10 KiB with the default limits) lives
 * in your memory and any number may coexist. Not reentrant per context.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#ifndef IT2N_INST_H
#define IT2N_INST_H

#include "it2n_link.h"

typedef struct it2n_inst_cfg {
    /* Write len bytes to the line: all of them, 0; or < 0 on failure. */
    int (*write)(void *user, const uint8_t *buf, size_t len);
    /* Milliseconds from any origin, wrapping at 2^32. */
    uint32_t (*now_ms)(void *user);
    /* Optional: up to len received bytes now (0 = none, < 0 = failure).
     * NULL: you call it2n_inst_feed instead. */
    int (*read)(void *user, uint8_t *buf, size_t len);
    /* Optional: called while waiting (e.g. __WFI()). */
    void (*idle)(void *user);
    void *user;          /* passed to the callbacks                  */
    uint32_t session_id; /* v1.1 only (version below): differs from
                                 every earlier session of this instrument.
                                 v1.2 (the default) needs none: the daemon
                                 hands out the session id, so the same
                                 boot every time is safe                  */
    uint16_t first_seq;  /* first sequence number (any; 0 is fine)  */
    uint32_t rto_ms;     /* retransmission timeout; 0 = 200         */
    uint8_t max_tries;   /* transmissions before giving up; 0 = 20  */
    uint32_t timeout_ms; /* longest wait of one call (read mode);
                                 0 = 10000                                */
    const char *node;    /* name sent in HELLO (<= 16 chars), or NULL */
    uint8_t version;     /* 0: protocol v1.2 (needs it2nd 1.2 or
                                 later); IT2N_PROTO_VERSION: v1.1, with
                                 session_id                              */
} it2n_inst_cfg;

typedef struct it2n_inst {
    it2n_link link;
    it2n_ostream os;
    it2n_inst_cfg cfg;
    int err; /* first failure (NACK or timeout), 0 none  */
    uint16_t err_seq;
    uint8_t err_type;
    it2n_msg_nack nack;   /* its detail (NACK)                        */
    uint8_t peer_hello;   /* the daemon's HELLO arrived               */
    it2n_msg_hello hello; /* ... and said this                        */
    uint8_t put_model, put_flags;
    it2n_msg msg;    /* PUT batch being filled; scratch          */
    int32_t q_seq;   /* QUERY awaiting its result, or -1         */
    int32_t barrier; /* CONFIGURE awaiting its answer, or -1     */
    uint8_t q_have;
    int q_code; /* NACK code of the last QUERY, 0 none       */
    it2n_msg_query_result *q_out;
    uint32_t puts, entries; /* PUT frames and entries sent              */
} it2n_inst;

/* it2n_inst holds a link context and a message: the library's name of
 * it2n_inst_open carries the options that size them (IT2N_PROTO_ABI). */
#define it2n_inst_open IT2N_PROTO_ABI(it2n_inst_open)

/*
 * Start a session: initialise ctx from cfg and send HELLO (the first frame;
 * v1.2: with session 0, the daemon's HELLO answers with the session id every
 * later frame carries; v1.1: with cfg->session_id). Returns IT2N_OK,
 * IT2N_ERR_INVAL (missing callback, unknown version) or a link error. In
 * read mode it waits for the HELLO's answer (v1.2: the daemon's HELLO).
 * v1.2: if the daemon later forgets the session (it restarted), the link
 * sends this HELLO again by itself and goes on in the new session.
 */
int it2n_inst_open(it2n_inst *ctx, const it2n_inst_cfg *cfg);

/*
 * Feed bytes received from the line (any chunking), e.g. from the UART
 * receive buffer. ACKs, NACKs, the daemon's HELLO and QUERY_RESULTs are
 * handled here. Always IT2N_OK.
 */
int it2n_inst_feed(it2n_inst *ctx, const uint8_t *data, size_t len);

/*
 * Retransmit what is due; in read mode also read what is there. Call it
 * from the main loop. Returns 0, or the first failure (as it2n_inst_error).
 */
int it2n_inst_poll(it2n_inst *ctx);

/*
 * CONFIGURE model (0..254) as n x m (1..7 each) with IT2N_F_* flags; its
 * points are cleared. A barrier (docs/protocol.md 4.2 rule 7): it goes out
 * once everything before it is answered, and nothing follows it until it
 * is answered (feed mode: the calls after it return BUSY meanwhile).
 * Returns IT2N_OK (sent), IT2N_PROTO_ERR_BUSY (feed
 * mode, window full: poll/feed and call again), a field error
 * (IT2N_PROTO_ERR_FIELD: nothing sent) or an earlier failure.
 */
int it2n_inst_configure(it2n_inst *ctx, uint8_t model, uint8_t n, uint8_t m, uint8_t flags);

/*
 * CONFIGURE model (0..254) as a cubic not-a-knot B-spline of n x m
 * intervals (1..255 each: up to 256 x 256 points) with IT2N_F_Z and/or
 * IT2N_F_TYPE1 (uniform parameters only: no IT2N_F_CHORD), the v1.3 form
 * (docs/protocol.md 5.3). Its points are cleared; a barrier as
 * it2n_inst_configure. Sent only to a daemon whose HELLO announced
 * IT2N_CAP_BSPLINE: an older one (v1.2) gets nothing and the call returns
 * IT2N_PROTO_ERR_VERSION (it would take the frame for a malformed
 * CONFIGURE). The daemon checks the sizes against the model's storage
 * (NACK RANGE) and its kind (NACK INVAL: the model is Bezier). Returns as
 * it2n_inst_configure.
 */
int it2n_inst_configure_bspline(it2n_inst *ctx, uint8_t model, uint8_t n, uint8_t m, uint8_t flags);

/*
 * One footprint fp (enum it2n_fp) of grid point (i, j) of model: vals are
 * x, y, z, T, I, F in Q24 (IT2N_VAL_ONE = 1.0); i, j 0..255 (the
 * daemon refuses those beyond the model's n, m: NACK INVAL). Batched: a PUT frame
 * leaves when full (as many entries as the daemon accepts), when another
 * model is addressed, or on it2n_inst_flush / it2n_inst_commit. Returns as
 * it2n_inst_configure; on IT2N_PROTO_ERR_BUSY the entry was NOT taken.
 */
int it2n_inst_put(it2n_inst *ctx, uint8_t model, uint8_t i, uint8_t j, uint8_t fp, const it2n_val vals[IT2N_CH_COUNT]);

/*
 * it2n_inst_put with vals in the core's fine layout: x, y, z in Q24, T, I,
 * F in Q30 (IT2N_MEMB_ONE = 1.0), what it2n_parse_memb gives, so the
 * daemon stores exactly what 'it2n' reads from the same text. Sent in a
 * PUT with IT2N_PUT_FINE (protocol v1.3) to a daemon whose HELLO announced
 * IT2N_CAP_FINE. To an older daemon (or before its HELLO arrived) the
 * entry goes as Q24 when every membership is a multiple of 2^-24 (exact:
 * the same model), else nothing is taken and the call returns
 * IT2N_PROTO_ERR_VERSION (the daemon would refuse the flag, and rounding
 * would give another model than 'it2n'). Batched as it2n_inst_put (a
 * batch holds one layout: changing it sends the batch). Returns as
 * it2n_inst_put.
 */
int it2n_inst_put_fine(it2n_inst *ctx, uint8_t model, uint8_t i, uint8_t j, uint8_t fp,
                       const it2n_val vals[IT2N_CH_COUNT]);

/* Send the PUT batch now, if any. Returns as it2n_inst_configure. */
int it2n_inst_flush(it2n_inst *ctx);

/* Flush, then COMMIT model (solve it). Returns as it2n_inst_configure. */
int it2n_inst_commit(it2n_inst *ctx, uint8_t model);

/*
 * Wait (read mode) until everything sent is answered. Returns IT2N_OK,
 * the first failure, or IT2N_PROTO_ERR_TIMEOUT after cfg.timeout_ms. In
 * feed mode it does not wait: IT2N_OK when all is answered, else
 * IT2N_PROTO_ERR_BUSY.
 */
int it2n_inst_sync(it2n_inst *ctx);

/*
 * QUERY model at (u, w) in Q2.30 wire parameters (IT2N_WIRE_PAR_ONE = 1.0;
 * it2n_par_to_wire converts the core's Q32). The result is stored in *out.
 * Read mode: waits for it (IT2N_OK, the NACK's code, e.g. IT2N_ERR_STATE
 * before COMMIT was acknowledged, or IT2N_PROTO_ERR_TIMEOUT). A refused
 * QUERY is not a failure of the context (it changed nothing). Feed mode:
 * returns IT2N_OK once sent; it2n_inst_query_done tells when *out is
 * filled. *out must stay valid until then.
 */
int it2n_inst_query(it2n_inst *ctx, uint8_t model, uint32_t u, uint32_t w, it2n_msg_query_result *out);

/* Feed mode: the last QUERY's result is in *out. */
bool it2n_inst_query_done(const it2n_inst *ctx);

/*
 * The first failure: 0, a NACK code (detail in *nack when not NULL: point,
 * footprint, channel, value, accepted range) or IT2N_PROTO_ERR_TIMEOUT.
 * Calls refuse to send after a failure until it2n_inst_resync.
 */
int it2n_inst_error(const it2n_inst *ctx, it2n_msg_nack *nack);

/*
 * Start over on the same line after a failure or when the daemon was lost:
 * drops what is in flight and the PUT batch, clears the error, starts a new
 * sequence (SYN) with sequence number first_seq and sends HELLO again
 * (v1.2: asks for a new session; v1.1: keeps the session id). Returns as
 * it2n_inst_open.
 */
int it2n_inst_resync(it2n_inst *ctx, uint16_t first_seq);

#endif /* IT2N_INST_H */
