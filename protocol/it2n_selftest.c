/*
 * Freestanding self-test of the wire format: every golden vector is packed,
 * framed and compared byte for byte with the expected frame (generated into
 * it2n_vectors.inc from protocol/vectors/), then decoded back and compared
 * with the packed payload. Runs on the host and on an emulated Cortex-M3.
 * Stack: about 3.5 KiB (one message, one payload, one decoder).
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include <string.h>

#include "it2n_msg.h"

typedef struct golden {
    const uint8_t *bytes;
    uint16_t len;
} golden;

#include "it2n_vectors.inc"

/* memcmp is not among the symbols a freestanding build may import. */
static bool same(const uint8_t *a, const uint8_t *b, size_t n)
{
    size_t k;
    for (k = 0; k < n; k++)
        if (a[k] != b[k])
            return false;
    return true;
}

/* Output stream that compares instead of storing. */
typedef struct cmp_state {
    const uint8_t *want;
    size_t len, pos;
    int bad;
} cmp_state;

static int cmp_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    cmp_state *c = (cmp_state *)s->state;
    if (len > c->len - c->pos || !same(c->want + c->pos, buf, len))
        c->bad = 1;
    else
        c->pos += len;
    return 0;
}

typedef struct selftest_mem {
    it2n_msg msg, back;
    uint8_t payload[IT2N_FRAME_MAX_LEN];
    it2n_frame_decoder dec;
} selftest_mem;

static int check_one(unsigned k, selftest_mem *t)
{
    const golden *g = &it2n_golden[k];
    it2n_frame_hdr hdr, got;
    const uint8_t *p = NULL;
    cmp_state cs;
    it2n_ostream os;
    size_t used = 0;
    int len, r;
    unsigned sess, b;

    if (it2n_proto_vector(k, &hdr, &t->msg) == NULL)
        return 1;
    sess = ((hdr.flags & IT2N_FLAG_SYN) != 0u || hdr.version == IT2N_PROTO_VERSION_12) ? IT2N_FRAME_SESSION_SIZE : 0u;
    len = it2n_msg_pack(&t->msg, t->payload + sess, IT2N_PROTO_MAX_PAYLOAD, NULL);
    if (len < 0)
        return 2;
    for (b = 0; b < sess; b++) /* SYN or v1.2 frame: session id, message */
        t->payload[b] = (uint8_t)((IT2N_VECTOR_SESSION >> (8u * b)) & 0xFFu);
    len += (int)sess;
    hdr.len = (uint16_t)len;
    cs.want = g->bytes;
    cs.len = g->len;
    cs.pos = 0;
    cs.bad = 0;
    os.write = cmp_write;
    os.state = &cs;
    r = it2n_frame_write(&os, &hdr, t->payload, (size_t)len);
    if (r < 0 || cs.bad || cs.pos != g->len || (size_t)r != g->len)
        return 3;
    it2n_frame_decoder_init(&t->dec);
    r = it2n_frame_decode(&t->dec, g->bytes, g->len, &used, &got, &p);
    if (r != 1 || used != g->len || got.type != hdr.type || got.version != hdr.version || got.seq != hdr.seq ||
        got.flags != hdr.flags || got.len != hdr.len || !same(p, t->payload, got.len))
        return 4;
    if (it2n_msg_unpack(got.type, p + sess, got.len - sess, &t->back, NULL) != IT2N_OK)
        return 5;
    /* Re-pack what was parsed: must give the same payload again. */
    len = it2n_msg_pack(&t->back, t->dec.buf, sizeof t->dec.buf, NULL);
    if (len != (int)(got.len - sess) || !same(t->dec.buf, t->payload + sess, got.len - sess))
        return 6;
    return 0;
}

int it2n_proto_selftest(void)
{
    static const uint8_t check[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    selftest_mem t;
    unsigned k;

    if (it2n_crc32c(check, sizeof check) != 0xE3069283u)
        return -1;
    if (sizeof it2n_golden / sizeof it2n_golden[0] != IT2N_VECTOR_COUNT)
        return -2;
    for (k = 0; k < IT2N_VECTOR_COUNT; k++) {
        int r = check_one(k, &t);
        if (r != 0)
            return -(int)(10u + 10u * k + (unsigned)r);
    }
    return 0;
}
