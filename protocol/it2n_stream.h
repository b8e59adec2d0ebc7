/*
 * it2n — byte stream interface for the serial protocol.
 *
 * In the spirit of nanopb's pb_ostream_t / pb_istream_t: a callback plus an
 * opaque state pointer, so the same protocol code drives a UART ring buffer
 * on a microcontroller and a file descriptor on Linux. Portable C99.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#ifndef IT2N_STREAM_H
#define IT2N_STREAM_H

#include <stddef.h>
#include <stdint.h>

typedef struct it2n_ostream it2n_ostream;
typedef struct it2n_istream it2n_istream;

/*
 * Output stream. Contract of write():
 *  - called with 1 <= len <= 255 bytes (the encoder's block size); buf is
 *    only valid during the call;
 *  - must accept all len bytes (block, queue or drop them) and return 0, or
 *    return a negative value on a fatal I/O error; the protocol then reports
 *    IT2N_PROTO_ERR_STREAM and the frame counts as lost (a reliable frame is
 *    retransmitted later, so dropping bytes is safe, just slow);
 *  - never called re-entrantly for the same stream; a frame is written by a
 *    run of calls with no other frame interleaved.
 * state is owned by the callback; the protocol never touches it.
 */
struct it2n_ostream {
    int (*write)(it2n_ostream *s, const uint8_t *buf, size_t len);
    void *state;
};

/*
 * Input stream. Contract of read():
 *  - called with len >= 1; copies at most len bytes that are available NOW
 *    into buf and returns their count; 0 means "nothing at the moment" and
 *    must not block indefinitely (non-blocking fd, empty ring buffer);
 *  - returns a negative value on a fatal error or end of stream;
 *  - bytes may arrive split at any position; the decoder does not care.
 */
struct it2n_istream {
    int (*read)(it2n_istream *s, uint8_t *buf, size_t len);
    void *state;
};

#endif /* IT2N_STREAM_H */
