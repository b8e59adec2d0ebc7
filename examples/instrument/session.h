/*
 * Instrument side of an it2n protocol session, written the way firmware
 * would be: no heap, fixed buffers, driven by the main loop with `now`.
 * It streams HELLO, CONFIGURE, the data set as PUT batches and COMMIT, and
 * finishes when everything is ACKed, or fails on the first NACK/timeout.
 */
#ifndef INSTRUMENT_SESSION_H
#define INSTRUMENT_SESSION_H

#include "it2n_link.h"

enum session_state {
    SESSION_RUNNING = 0,
    SESSION_DONE = 1,   /* all ACKed (or all sent, one-way) */
    SESSION_FAILED = -1 /* NACK or timeout: see nack / fail_code */
};

typedef struct session {
    it2n_link link;
    const it2n_dataset *ds;
    uint8_t model;
    bool oneway; /* no peer answers: send once, don't wait */
    /* progress through the data set: next (i, j, fp) to PUT */
    unsigned step; /* 0 HELLO, 1 CONFIGURE, 2 PUTs, 3 COMMIT, 4 sent */
    unsigned i, j, fp;
    unsigned puts, entries;
    int state;
    int fail_code;
    uint16_t fail_seq;
    uint8_t fail_type;
    it2n_msg_nack nack;
    it2n_ostream *out;
    it2n_frame_hdr ow_hdr; /* one-way mode: frame counter */
    uint32_t peer_caps;    /* the daemon's HELLO caps: IT2N_CAP_FINE lets
                              PUTs carry Q30 memberships (v1.3)       */
} session;

/* Start a session sending ds as model `model` through out/in, in protocol
 * v1.2: the daemon hands out the session id, so a restarted instrument is
 * never taken for a retransmission of its previous run. One-way mode
 * (nothing is read back) speaks v1.1 and needs session_id, different from
 * every earlier session of this instrument (random, or a boot counter). */
int session_init(session *s, const it2n_dataset *ds, uint8_t model, it2n_ostream *out, it2n_istream *in,
                 uint32_t rto_ms, uint8_t tries, bool oneway, uint16_t first_seq, uint32_t session_id);

/* Do whatever is possible now: read input, retransmit, send the next
 * messages while the window allows. Returns the session state. */
int session_step(session *s, uint32_t now);

/* Milliseconds the main loop may sleep before calling session_step. */
uint32_t session_idle_ms(const session *s, uint32_t now);

#endif
