/*
 * Frame encoder (buffer and stream flavours) and the streaming decoder.
 * The decoder unstuffs COBS byte by byte, so it never needs the stuffed
 * frame in memory and accepts input split at any position.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include <string.h>

#include "it2n_proto.h"

static void put_hdr(uint8_t *h, const it2n_frame_hdr *hdr)
{
    h[0] = hdr->version;
    h[1] = hdr->type;
    h[2] = hdr->flags;
    h[3] = 0u;
    h[4] = (uint8_t)(hdr->seq & 0xFFu);
    h[5] = (uint8_t)(hdr->seq >> 8);
    h[6] = (uint8_t)(hdr->len & 0xFFu);
    h[7] = (uint8_t)(hdr->len >> 8);
}

static void put_crc(uint8_t *c, uint32_t crc)
{
    c[0] = (uint8_t)(crc & 0xFFu);
    c[1] = (uint8_t)((crc >> 8) & 0xFFu);
    c[2] = (uint8_t)((crc >> 16) & 0xFFu);
    c[3] = (uint8_t)(crc >> 24);
}

static uint32_t frame_crc(const uint8_t *h, const uint8_t *payload, size_t len)
{
    uint32_t crc = it2n_crc32c_update(IT2N_CRC32C_INIT, h, IT2N_FRAME_HDR_SIZE);
    if (len > 0u)
        crc = it2n_crc32c_update(crc, payload, len);
    return crc ^ 0xFFFFFFFFu;
}

/* ---- Stream encoder: one COBS block buffered at a time ------------------ */

typedef struct cobs_out {
    it2n_ostream *os;
    uint8_t blk[255]; /* blk[0] is the code byte, filled when flushing */
    uint8_t n;        /* data bytes in blk[1..]                        */
    int err;
    size_t total;
} cobs_out;

static void cobs_flush(cobs_out *c)
{
    c->blk[0] = (uint8_t)(c->n + 1u);
    if (c->err == 0 && c->os->write(c->os, c->blk, (size_t)c->n + 1u) < 0)
        c->err = IT2N_PROTO_ERR_STREAM;
    c->total += (size_t)c->n + 1u;
    c->n = 0;
}

static void cobs_put(cobs_out *c, const uint8_t *p, size_t len)
{
    size_t k;
    for (k = 0; k < len; k++) {
        if (c->n == 254u) /* full block: code 0xFF, no implied zero */
            cobs_flush(c);
        if (p[k] == 0u)
            cobs_flush(c);
        else
            c->blk[1u + c->n++] = p[k];
    }
}

int it2n_frame_write(it2n_ostream *os, const it2n_frame_hdr *hdr, const uint8_t *payload, size_t len)
{
    uint8_t h[IT2N_FRAME_HDR_SIZE], c[IT2N_FRAME_CRC_SIZE];
    static const uint8_t delim = 0u;
    cobs_out co;

    if (len > IT2N_FRAME_MAX_LEN || hdr->len != len)
        return IT2N_PROTO_ERR_OVERSIZE;
    put_hdr(h, hdr);
    put_crc(c, frame_crc(h, payload, len));
    co.os = os;
    co.n = 0;
    co.err = 0;
    co.total = 0;
    cobs_put(&co, h, sizeof h);
    if (len > 0u)
        cobs_put(&co, payload, len);
    cobs_put(&co, c, sizeof c);
    cobs_flush(&co);
    if (co.err == 0 && os->write(os, &delim, 1u) < 0)
        co.err = IT2N_PROTO_ERR_STREAM;
    return co.err != 0 ? co.err : (int)(co.total + 1u);
}

/* ---- Buffer encoder: the same stream code writing into memory ---------- */

typedef struct buf_sink {
    uint8_t *p;
    size_t cap, len;
} buf_sink;

static int buf_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    buf_sink *b = (buf_sink *)s->state;
    if (len > b->cap - b->len)
        return -1;
    memcpy(b->p + b->len, buf, len);
    b->len += len;
    return 0;
}

int it2n_frame_encode(const it2n_frame_hdr *hdr, const uint8_t *payload, size_t len, uint8_t *out, size_t cap)
{
    buf_sink b;
    it2n_ostream os;
    int r;

    b.p = out;
    b.cap = cap;
    b.len = 0;
    os.write = buf_write;
    os.state = &b;
    r = it2n_frame_write(&os, hdr, payload, len);
    return r == IT2N_PROTO_ERR_STREAM ? IT2N_PROTO_ERR_NOSPACE : r;
}

/* ---- Streaming decoder -------------------------------------------------- */

void it2n_frame_decoder_init(it2n_frame_decoder *d)
{
    memset(d, 0, sizeof *d);
}

static void dec_reset(it2n_frame_decoder *d)
{
    d->len = 0;
    d->code = 0;
    d->zero = 0;
    d->overflow = 0;
    d->started = 0;
}

static void dec_append(it2n_frame_decoder *d, uint8_t b)
{
    if (d->len >= IT2N_FRAME_MAX_RAW)
        d->overflow = 1;
    else
        d->buf[d->len++] = b;
}

/* A delimiter arrived: judge the frame collected so far. */
static int dec_finish(it2n_frame_decoder *d, it2n_frame_hdr *hdr, const uint8_t **payload)
{
    const uint8_t *b = d->buf;
    uint32_t crc;
    size_t plen;

    if (d->overflow) {
        d->stats.oversize++;
        return IT2N_PROTO_ERR_OVERSIZE;
    }
    if (d->code != 0u) { /* block promised more bytes than arrived */
        d->stats.cobs++;
        return IT2N_PROTO_ERR_COBS;
    }
    if (d->len < IT2N_FRAME_MIN_RAW) {
        d->stats.shortf++;
        return IT2N_PROTO_ERR_SHORT;
    }
    plen = (size_t)d->len - IT2N_FRAME_MIN_RAW;
    crc = frame_crc(b, b + IT2N_FRAME_HDR_SIZE, plen);
    if ((uint32_t)(b[d->len - 4u] | ((uint32_t)b[d->len - 3u] << 8) | ((uint32_t)b[d->len - 2u] << 16) |
                   ((uint32_t)b[d->len - 1u] << 24)) != crc) {
        d->stats.crc++;
        return IT2N_PROTO_ERR_CRC;
    }
    hdr->version = b[0];
    hdr->type = b[1];
    hdr->flags = b[2];
    hdr->seq = (uint16_t)(b[4] | (b[5] << 8));
    hdr->len = (uint16_t)(b[6] | (b[7] << 8));
    *payload = b + IT2N_FRAME_HDR_SIZE;
    if (hdr->len != plen) {
        d->stats.length++;
        return IT2N_PROTO_ERR_LENGTH;
    }
    if (hdr->version < IT2N_PROTO_VERSION_MIN || hdr->version > IT2N_PROTO_VERSION_MAX) {
        d->stats.version++;
        return IT2N_PROTO_ERR_VERSION;
    }
    d->stats.ok++;
    return 1;
}

int it2n_frame_decode(it2n_frame_decoder *d, const uint8_t *data, size_t len, size_t *used, it2n_frame_hdr *hdr,
                      const uint8_t **payload)
{
    size_t k;

    for (k = 0; k < len; k++) {
        uint8_t b = data[k];
        if (b == 0u) {
            int r;
            if (!d->started)
                continue; /* empty frame: idle fill or resync */
            r = dec_finish(d, hdr, payload);
            dec_reset(d);
            *used = k + 1u;
            return r;
        }
        d->started = 1;
        if (d->overflow)
            continue;
        if (d->code == 0u) { /* a code byte opens the next block */
            if (d->zero)
                dec_append(d, 0u);
            d->code = (uint8_t)(b - 1u);
            d->zero = b != 0xFFu;
        } else {
            dec_append(d, b);
            d->code--;
        }
    }
    *used = len;
    return 0;
}
