/*
 * it2n — serial framing protocol: limits, error codes, CRC, COBS, frames.
 *
 * Wire format (docs/protocol.md is the normative text):
 *   frame   = COBS(header || payload || crc32c) 0x00
 *   header  = version u8, type u8, flags u8, reserved u8, seq u16le, len u16le
 *   crc32c  = CRC-32C (Castagnoli) over header and payload, u32le
 *
 * Portable C99: no heap, no floating point, no global mutable state. Every
 * context lives in caller memory; any number of them may coexist.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#ifndef IT2N_PROTO_H
#define IT2N_PROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "it2n.h"
#include "it2n_stream.h"

/* ---- Compile-time limits (override with -D; both peers must agree) ------ */

/* Largest payload of one frame, bytes. Must hold the largest fixed-size
 * message (LOCATE_RESULT, 474 bytes) and fit the u16 length field. */
#ifndef IT2N_PROTO_MAX_PAYLOAD
#define IT2N_PROTO_MAX_PAYLOAD 1024
#endif

/* Largest window this build supports: reliable frames in flight per
 * direction (sender slots = receiver duplicate history = reorder buffer).
 * The window actually used is negotiated per peer (HELLO `window`, see
 * it2n_link_set_peer) and may be set lower per link (it2n_link_cfg.window).
 * A power of two (so seq % W stays in step across the 16-bit wrap), 4..64
 * (a plain decimal literal: it is part of the
 * library's link-time names, see it2n_link.h). 4 keeps MCU RAM small; the
 * daemon and host tools are built with 16. Every user of a library must
 * compile with the value it was built with (pkg-config / CMake pass it on;
 * a mismatch fails to link). */
#ifndef IT2N_PROTO_WINDOW
#define IT2N_PROTO_WINDOW 4
#endif

/* Protocol constant: the window every receiver supports, and what a sender
 * keeps to until the peer's HELLO announced its own (docs/protocol.md 4.2). */
#define IT2N_PROTO_WINDOW_MIN 4

#if IT2N_PROTO_MAX_PAYLOAD < 480 || IT2N_PROTO_MAX_PAYLOAD > 65535
#error "IT2N_PROTO_MAX_PAYLOAD must be within 480..65535"
#endif
#if IT2N_PROTO_WINDOW < 4 || IT2N_PROTO_WINDOW > 64 || (IT2N_PROTO_WINDOW & (IT2N_PROTO_WINDOW - 1)) != 0
#error "IT2N_PROTO_WINDOW must be a power of two within 4..64"
#endif

/* Protocol version carried in every header (docs/protocol.md section 6):
 * wire version 2 is protocol v1.1, what a link speaks unless configured
 * for v1.2 (wire version 1 was v1.0). */
#define IT2N_PROTO_VERSION 2
/* Wire version 3 is protocol v1.2: every frame carries the session id the
 * server handed out (docs/protocol.md 4.1), so an instrument needs no
 * entropy or storage of its own to be told from its previous life. */
#define IT2N_PROTO_VERSION_12 3
/* Versions this implementation speaks (v1.0 peers are refused). */
#define IT2N_PROTO_VERSION_MIN 2
#define IT2N_PROTO_VERSION_MAX 3

/* Receiver reorder buffer: frames arriving ahead of the expected one
 * (within the window) are kept and delivered once the gap is filled.
 * 1 (default) keeps IT2N_PROTO_WINDOW frames, ~1 KiB each; 0 drops them
 * (the sender retransmits), for the smallest RAM. */
#ifndef IT2N_PROTO_RX_REORDER
#define IT2N_PROTO_RX_REORDER 1
#endif

/* Link-time ABI guard. The protocol's structs are sized by the window, the
 * payload, the reorder buffer and (it2n_msg) IT2N_MAX_DEGREE: the entry
 * points every use of them starts with (it2n_link_init, it2n_inst_open,
 * it2n_frame_decoder_init, it2n_msg_pack/unpack, it2n_proto_vector) are
 * named after the values, e.g.
 * it2n_inst_open_abi_window16_payload1024_reorder1_degree7, so a program
 * compiled with other values than the library fails to link (the undefined
 * name says what the program asked for; `nm` on the library shows what it
 * was built with) instead of overrunning a context. Callers use the plain
 * names. Window, payload and degree must be plain decimal literals. */
#if IT2N_PROTO_RX_REORDER
#define IT2N_ABI_REORDER_ 1
#else
#define IT2N_ABI_REORDER_ 0
#endif
#define IT2N_ABI_PROTO_(f, w, p, r, d) f##_abi_window##w##_payload##p##_reorder##r##_degree##d
#define IT2N_ABI_PROTO(f, w, p, r, d) IT2N_ABI_PROTO_(f, w, p, r, d)
#define IT2N_PROTO_ABI(f) \
    IT2N_ABI_PROTO(f, IT2N_PROTO_WINDOW, IT2N_PROTO_MAX_PAYLOAD, IT2N_ABI_REORDER_, IT2N_MAX_DEGREE)

#define IT2N_FRAME_HDR_SIZE 8
#define IT2N_FRAME_CRC_SIZE 4
/* A SYN frame's payload starts with the sender's u32 session id, then the
 * message (v1.1); in v1.2 every frame's does. So a frame's len is at most
 * the message limit + 4. */
#define IT2N_FRAME_SESSION_SIZE 4
#define IT2N_FRAME_MAX_LEN (IT2N_PROTO_MAX_PAYLOAD + IT2N_FRAME_SESSION_SIZE)
/* Frame before stuffing: header + payload + CRC. */
#define IT2N_FRAME_MIN_RAW (IT2N_FRAME_HDR_SIZE + IT2N_FRAME_CRC_SIZE)
#define IT2N_FRAME_MAX_RAW (IT2N_FRAME_MIN_RAW + IT2N_FRAME_MAX_LEN)
/* COBS adds one byte per started 254-byte block; plus the 0x00 delimiter. */
#define IT2N_COBS_MAX(n) ((n) + (n) / 254u + 1u)
#define IT2N_FRAME_MAX_WIRE (IT2N_COBS_MAX(IT2N_FRAME_MAX_RAW) + 1u)

/* Header flags. */
#define IT2N_FLAG_REL 0x01u /* reliable: receiver answers ACK or NACK     */
#define IT2N_FLAG_SYN \
    0x02u                    /* first frame of a sequence; payload starts
                                with the sender's u32 session id       */
#define IT2N_FLAG_RETX 0x04u /* retransmission (informational only)       */

/* ---- Errors (negative, disjoint from enum it2n_error) ------------------- */

enum it2n_proto_error {
    IT2N_PROTO_ERR_COBS = -100,     /* bad byte stuffing / truncated frame  */
    IT2N_PROTO_ERR_SHORT = -101,    /* frame shorter than header + CRC      */
    IT2N_PROTO_ERR_CRC = -102,      /* CRC mismatch                         */
    IT2N_PROTO_ERR_OVERSIZE = -103, /* frame larger than IT2N_FRAME_MAX_RAW */
    IT2N_PROTO_ERR_LENGTH = -104,   /* header length != payload length      */
    IT2N_PROTO_ERR_VERSION = -105,  /* unsupported protocol version         */
    IT2N_PROTO_ERR_TYPE = -106,     /* unknown message type                 */
    IT2N_PROTO_ERR_PAYLOAD = -107,  /* payload size wrong for its type      */
    IT2N_PROTO_ERR_FIELD = -108,    /* field outside its documented range   */
    IT2N_PROTO_ERR_NOSYNC = -109,   /* receiver has no sequence: send SYN   */
    IT2N_PROTO_ERR_BUSY = -110,     /* send window full, try later          */
    IT2N_PROTO_ERR_TIMEOUT = -111,  /* retransmissions exhausted            */
    IT2N_PROTO_ERR_STREAM = -112,   /* stream callback failed               */
    IT2N_PROTO_ERR_MODEL = -113,    /* unknown / unusable model id          */
    IT2N_PROTO_ERR_SEQ = -114,      /* sequence number not awaiting an ACK  */
    IT2N_PROTO_ERR_NOSPACE = -115,  /* buffer too small / response larger
                                       than the peer's max_payload       */
    IT2N_PROTO_ERR_DOWN = -116,     /* link declared down: frame dropped  */
    IT2N_PROTO_ERR_SESSION = -117   /* v1.2: session id unknown to the
                                       receiver: send HELLO for a new one */
};

/* Short English description of a protocol error code (-100..); for the
 * core's codes (-1..-10) it says "core error": use it2n_strerror, which
 * lives in the core so that protocol/ links without it. */
const char *it2n_proto_strerror(int code);

/* Where and why a parse failed: code, payload byte offset of the offending
 * field, the value found and the limit it broke (0 when meaningless). */
typedef struct it2n_proto_errinfo {
    int code;
    uint16_t offset;
    int64_t value;
    int64_t limit;
} it2n_proto_errinfo;

/* ---- CRC-32C ------------------------------------------------------------ */

/* Start value for it2n_crc32c_update. */
#define IT2N_CRC32C_INIT 0xFFFFFFFFu

/* Fold len bytes into a running (not yet inverted) CRC-32C. */
uint32_t it2n_crc32c_update(uint32_t crc, const uint8_t *p, size_t len);

/* CRC-32C of a buffer (reflected 0x1EDC6F41, init and xorout 0xFFFFFFFF);
 * "123456789" gives 0xE3069283. */
uint32_t it2n_crc32c(const uint8_t *p, size_t len);

/* ---- COBS --------------------------------------------------------------- */

/*
 * COBS-encode len bytes of src into dst (capacity cap), no delimiter.
 * Returns the encoded length (<= IT2N_COBS_MAX(len)) or
 * IT2N_PROTO_ERR_NOSPACE. src and dst must not overlap.
 */
int it2n_cobs_encode(const uint8_t *src, size_t len, uint8_t *dst, size_t cap);

/*
 * Decode one COBS block sequence (no 0x00 inside, no delimiter) of len bytes
 * into dst. Returns the decoded length, IT2N_PROTO_ERR_COBS on a zero byte
 * or a code pointing past the end, or IT2N_PROTO_ERR_NOSPACE.
 */
int it2n_cobs_decode(const uint8_t *src, size_t len, uint8_t *dst, size_t cap);

/* ---- Frames ------------------------------------------------------------- */

typedef struct it2n_frame_hdr {
    uint8_t version; /* IT2N_PROTO_VERSION when sending          */
    uint8_t type;    /* enum it2n_msg_type                       */
    uint8_t flags;   /* IT2N_FLAG_*                               */
    uint16_t seq;    /* sequence number (reliable frames)        */
    uint16_t len;    /* payload length, <= IT2N_PROTO_MAX_PAYLOAD */
} it2n_frame_hdr;

/*
 * Encode a complete wire frame (stuffed, with trailing 0x00) into out.
 * hdr->len must equal len. Returns the wire length or
 * IT2N_PROTO_ERR_NOSPACE / IT2N_PROTO_ERR_OVERSIZE; out untouched on error
 * except for NOSPACE, where it may be partly written.
 */
int it2n_frame_encode(const it2n_frame_hdr *hdr, const uint8_t *payload, size_t len, uint8_t *out, size_t cap);

/*
 * Same, written through an output stream in blocks of at most 255 bytes,
 * with only a 255-byte buffer on the stack. Returns the wire length,
 * IT2N_PROTO_ERR_OVERSIZE or IT2N_PROTO_ERR_STREAM.
 */
int it2n_frame_write(it2n_ostream *os, const it2n_frame_hdr *hdr, const uint8_t *payload, size_t len);

/* Decoder statistics: frames accepted and dropped per reason. */
typedef struct it2n_frame_stats {
    uint32_t ok, cobs, shortf, crc, oversize, length, version;
} it2n_frame_stats;

/*
 * Streaming decoder: bytes in, one frame at a time out. Unstuffs on the fly
 * into buf, so memory is IT2N_FRAME_MAX_RAW plus a few bytes. After any
 * error it resynchronises at the next 0x00; at most the damaged frame is
 * lost. Empty frames (0x00 0x00) are ignored, so a sender may start with a
 * 0x00 to flush garbage at the receiver.
 */
typedef struct it2n_frame_decoder {
    uint16_t len;     /* bytes unstuffed so far                  */
    uint8_t code;     /* bytes left in the current COBS block    */
    uint8_t zero;     /* a 0x00 is due before the next block     */
    uint8_t overflow; /* frame too long: skipping to delimiter   */
    uint8_t started;  /* at least one byte since last delimiter  */
    it2n_frame_stats stats;
    uint8_t buf[IT2N_FRAME_MAX_RAW];
} it2n_frame_decoder;

/* Reset a decoder (also clears its statistics). */
#define it2n_frame_decoder_init IT2N_PROTO_ABI(it2n_frame_decoder_init)
void it2n_frame_decoder_init(it2n_frame_decoder *d);

/*
 * Feed bytes. Stops after the first completed or dropped frame and stores in
 * *used how many bytes it consumed (call again with the rest). Returns
 *   0   all bytes consumed, no frame complete yet;
 *   1   a valid frame: *hdr filled, *payload points into d->buf and stays
 *       valid until the next call;
 *   <0  a frame was dropped (IT2N_PROTO_ERR_COBS, _SHORT, _CRC, _OVERSIZE,
 *       _LENGTH, _VERSION). For _VERSION (CRC good) *hdr is filled so the
 *       receiver can answer the peer.
 */
int it2n_frame_decode(it2n_frame_decoder *d, const uint8_t *data, size_t len, size_t *used, it2n_frame_hdr *hdr,
                      const uint8_t **payload);

/*
 * Freestanding self-test: re-encodes every golden vector (protocol/vectors/)
 * from a const table, compares bytes and decodes them back. Returns 0, or
 * -(number of the first failing check). No stdio, no heap.
 */
int it2n_proto_selftest(void);

#endif /* IT2N_PROTO_H */
