/* Unit tests: CRC-32C, COBS, frame encoder and streaming decoder edges. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "proto_test.h"

static uint8_t payload[IT2N_PROTO_MAX_PAYLOAD];
static uint8_t wire[4 * IT2N_FRAME_MAX_WIRE];

static void test_crc_check_value(void **st)
{
    (void)st;
    assert_int_equal(it2n_crc32c((const uint8_t *)"123456789", 9), 0xE3069283u);
    assert_int_equal(it2n_crc32c(NULL, 0), 0);
    /* Incremental equals one-shot. */
    uint32_t c = it2n_crc32c_update(IT2N_CRC32C_INIT, (const uint8_t *)"1234", 4);
    c = it2n_crc32c_update(c, (const uint8_t *)"56789", 5) ^ 0xFFFFFFFFu;
    assert_int_equal(c, 0xE3069283u);
}

static void cobs_roundtrip(const uint8_t *src, size_t len, size_t want_len)
{
    static uint8_t enc[IT2N_COBS_MAX(2000)], dec[2000];
    int e = it2n_cobs_encode(src, len, enc, sizeof enc);
    assert_true(e > 0);
    if (want_len)
        assert_int_equal(e, want_len);
    assert_true((size_t)e <= IT2N_COBS_MAX(len));
    for (int k = 0; k < e; k++)
        assert_int_not_equal(enc[k], 0);
    int d = it2n_cobs_decode(enc, (size_t)e, dec, sizeof dec);
    assert_int_equal(d, len);
    assert_memory_equal(dec, src, len);
    /* Exactly enough room works, one byte less fails cleanly. */
    assert_int_equal(it2n_cobs_encode(src, len, enc, (size_t)e), e);
    assert_int_equal(it2n_cobs_encode(src, len, enc, (size_t)e - 1), IT2N_PROTO_ERR_NOSPACE);
}

static void test_cobs_edges(void **st)
{
    (void)st;
    uint8_t b[2000] = {0};
    cobs_roundtrip(b, 0, 1); /* empty: single code byte 01 */
    memset(b, 0, sizeof b);
    cobs_roundtrip(b, 1, 2);
    cobs_roundtrip(b, 1000, 1001); /* zeros everywhere: 01 per zero + 1 */
    static const size_t runs[] = {1, 253, 254, 255, 508, 509, 1000};
    for (size_t r = 0; r < sizeof runs / sizeof runs[0]; r++) {
        memset(b, 0x5A, runs[r]);
        cobs_roundtrip(b, runs[r], runs[r] + (runs[r] + 253) / 254);
        /* run followed by a zero and more data */
        b[runs[r]] = 0;
        b[runs[r] + 1] = 7;
        cobs_roundtrip(b, runs[r] + 2, 0);
    }
    /* Known encodings from the COBS paper / Wikipedia. */
    static const uint8_t in1[] = {0x11, 0x22, 0x00, 0x33};
    static const uint8_t out1[] = {0x03, 0x11, 0x22, 0x02, 0x33};
    uint8_t enc[16];
    assert_int_equal(it2n_cobs_encode(in1, 4, enc, sizeof enc), 5);
    assert_memory_equal(enc, out1, 5);
    /* Decoder rejects zeros and codes running past the end. */
    static const uint8_t bad1[] = {0x03, 0x11, 0x00};
    static const uint8_t bad2[] = {0x05, 0x11, 0x22};
    assert_int_equal(it2n_cobs_decode(bad1, 3, enc, sizeof enc), IT2N_PROTO_ERR_COBS);
    assert_int_equal(it2n_cobs_decode(bad2, 3, enc, sizeof enc), IT2N_PROTO_ERR_COBS);
}

static int encode(uint8_t type, uint16_t seq, const uint8_t *p, size_t len, uint8_t *out, size_t cap)
{
    it2n_frame_hdr h = {IT2N_PROTO_VERSION, type, IT2N_FLAG_REL, seq, (uint16_t)len};
    return it2n_frame_encode(&h, p, len, out, cap);
}

/* Feed `len` bytes in chunks of `chunk`; collect results. */
typedef struct dec_log {
    int ok, err[8], nerr;
    it2n_frame_hdr last;
    uint8_t last_payload[IT2N_PROTO_MAX_PAYLOAD];
} dec_log;

static void feed(it2n_frame_decoder *d, const uint8_t *b, size_t len, size_t chunk, dec_log *lg)
{
    size_t pos = 0;
    while (pos < len) {
        size_t n = len - pos < chunk ? len - pos : chunk;
        while (n > 0) {
            size_t used = 0;
            const uint8_t *p = NULL;
            it2n_frame_hdr h;
            int r = it2n_frame_decode(d, b + pos, n, &used, &h, &p);
            assert_true(used >= 1 && used <= n);
            if (r == 1) {
                lg->ok++;
                lg->last = h;
                memcpy(lg->last_payload, p, h.len);
            } else if (r < 0 && lg->nerr < 8) {
                lg->err[lg->nerr++] = r;
            } else if (r < 0) {
                lg->nerr++;
            }
            pos += used;
            n -= used;
        }
    }
}

static it2n_frame_decoder dec;

static void roundtrip_payload(size_t len, size_t chunk)
{
    int w = encode(0x33, 0xBEEF, payload, len, wire, sizeof wire);
    assert_true(w > 0);
    assert_true((size_t)w <= IT2N_FRAME_MAX_WIRE);
    assert_int_equal(wire[w - 1], 0);
    for (int k = 0; k < w - 1; k++)
        assert_int_not_equal(wire[k], 0);
    it2n_frame_decoder_init(&dec);
    dec_log lg = {0};
    feed(&dec, wire, (size_t)w, chunk, &lg);
    assert_int_equal(lg.ok, 1);
    assert_int_equal(lg.nerr, 0);
    assert_int_equal(lg.last.type, 0x33);
    assert_int_equal(lg.last.seq, 0xBEEF);
    assert_int_equal(lg.last.flags, IT2N_FLAG_REL);
    assert_int_equal(lg.last.len, len);
    assert_memory_equal(lg.last_payload, payload, len);
}

static void test_frame_sizes_and_chunks(void **st)
{
    (void)st;
    static const size_t sizes[] = {0, 1, 241, 242, 243, 253, 254, 255, 500, IT2N_PROTO_MAX_PAYLOAD};
    static const size_t chunks[] = {1, 2, 7, 255, 100000};
    for (int fill = 0; fill < 3; fill++) {
        for (size_t k = 0; k < IT2N_PROTO_MAX_PAYLOAD; k++)
            payload[k] = fill == 0 ? 0 : fill == 1 ? 0xA5 : (uint8_t)(k * 7);
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++)
            for (size_t c = 0; c < sizeof chunks / sizeof chunks[0]; c++)
                roundtrip_payload(sizes[s], chunks[c]);
    }
    /* Over the maximum is refused by the encoder. */
    assert_int_equal(encode(1, 0, payload, IT2N_FRAME_MAX_LEN + 1, wire, sizeof wire),
                     IT2N_PROTO_ERR_OVERSIZE);
    /* Stream and buffer encoders give identical bytes; blocks <= 255. */
    mem_out *mo = calloc(1, sizeof *mo);
    it2n_ostream os = mem_stream(mo);
    it2n_frame_hdr h = {1, 9, 0, 1, IT2N_PROTO_MAX_PAYLOAD};
    int a = it2n_frame_write(&os, &h, payload, IT2N_PROTO_MAX_PAYLOAD);
    int b = it2n_frame_encode(&h, payload, IT2N_PROTO_MAX_PAYLOAD, wire, sizeof wire);
    assert_int_equal(a, b);
    assert_int_equal(mo->full, 0);
    assert_memory_equal(mo->buf, wire, (size_t)a);
    /* Too small a buffer: NOSPACE, stream failure: STREAM. */
    assert_int_equal(it2n_frame_encode(&h, payload, IT2N_PROTO_MAX_PAYLOAD, wire, 100),
                     IT2N_PROTO_ERR_NOSPACE);
    mo->fail = 1;
    assert_int_equal(it2n_frame_write(&os, &h, payload, IT2N_PROTO_MAX_PAYLOAD), IT2N_PROTO_ERR_STREAM);
    free(mo);
}

static void test_every_bit_flip_caught(void **st)
{
    (void)st;
    for (size_t k = 0; k < 40; k++)
        payload[k] = (uint8_t)(k * 37 + 1);
    payload[5] = 0; /* a delimiter-valued byte inside the payload */
    int w = encode(0x03, 77, payload, 40, wire, sizeof wire);
    assert_true(w > 0);
    uint8_t bad[256];
    for (int byte = 0; byte < w - 1; byte++) {
        for (int bit = 0; bit < 8; bit++) {
            memcpy(bad, wire, (size_t)w);
            bad[byte] ^= (uint8_t)(1u << bit);
            /* A flip may create a 0x00 (splitting the frame): then more
             * than one "frame" may end, but none may be accepted. */
            it2n_frame_decoder_init(&dec);
            dec_log lg = {0};
            feed(&dec, bad, (size_t)w, 1, &lg);
            assert_int_equal(lg.ok, 0);
            assert_true(lg.nerr >= 1);
        }
    }
    /* And the decoder still takes the next good frame. */
    dec_log lg = {0};
    feed(&dec, wire, (size_t)w, 3, &lg);
    assert_int_equal(lg.ok, 1);
}

static void test_truncation_every_offset(void **st)
{
    (void)st;
    for (size_t k = 0; k < 300; k++)
        payload[k] = (uint8_t)(k % 3 == 0 ? 0 : k);
    int w = encode(0x03, 5, payload, 300, wire, sizeof wire);
    static uint8_t buf[2 * IT2N_FRAME_MAX_WIRE];
    for (int cut = 0; cut < w - 1; cut++) {
        /* cut bytes of the frame, a delimiter, then the full frame. */
        memcpy(buf, wire, (size_t)cut);
        buf[cut] = 0;
        memcpy(buf + cut + 1, wire, (size_t)w);
        it2n_frame_decoder_init(&dec);
        dec_log lg = {0};
        feed(&dec, buf, (size_t)cut + 1 + (size_t)w, 64, &lg);
        assert_int_equal(lg.ok, 1);
        assert_int_equal(lg.nerr, cut == 0 ? 0 : 1); /* cut 0: empty frame, ignored */
        assert_int_equal(lg.last.len, 300);
        assert_memory_equal(lg.last_payload, payload, 300);
    }
}

static void test_garbage_between_frames(void **st)
{
    (void)st;
    uint64_t rng = 42;
    static uint8_t stream[64 * 1024];
    size_t pos = 0;
    int frames = 0;
    for (int f = 0; f < 40; f++) {
        size_t len = rng_below(&rng, 200);
        for (size_t k = 0; k < len; k++)
            payload[k] = (uint8_t)rng_next(&rng);
        pos += (size_t)encode(0x03, (uint16_t)f, payload, len, stream + pos, sizeof stream - pos);
        frames++;
        /* garbage: random bytes, then a delimiter so the next frame starts clean */
        size_t g = rng_below(&rng, 50);
        for (size_t k = 0; k < g; k++)
            stream[pos++] = (uint8_t)(rng_next(&rng) | 1);
        if (g)
            stream[pos++] = 0;
    }
    it2n_frame_decoder_init(&dec);
    dec_log lg = {0};
    feed(&dec, stream, pos, 13, &lg);
    assert_int_equal(lg.ok, frames);
    assert_int_equal(dec.stats.ok, (uint32_t)frames);
}

static void test_oversize_and_short(void **st)
{
    (void)st;
    static uint8_t junk[3 * IT2N_FRAME_MAX_WIRE];
    memset(junk, 0x11, sizeof junk);
    junk[sizeof junk - 1] = 0;
    it2n_frame_decoder_init(&dec);
    dec_log lg = {0};
    feed(&dec, junk, sizeof junk, 500, &lg);
    assert_int_equal(lg.ok, 0);
    assert_int_equal(lg.nerr, 1);
    assert_int_equal(lg.err[0], IT2N_PROTO_ERR_OVERSIZE);
    /* Short frame: valid COBS, 11 bytes. */
    uint8_t s[13] = {12, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 0};
    dec_log l2 = {0};
    feed(&dec, s, sizeof s, 1, &l2);
    assert_int_equal(l2.err[0], IT2N_PROTO_ERR_SHORT);
    /* Length field disagreeing with the frame, CRC recomputed: LENGTH. */
    uint8_t raw[12 + 4] = {1, 3, 1, 0, 0, 0, 5, 0, 9, 9, 9, 9};
    uint32_t c = it2n_crc32c(raw, 12);
    for (int k = 0; k < 4; k++)
        raw[12 + k] = (uint8_t)(c >> (8 * k));
    uint8_t enc[40];
    int e = it2n_cobs_encode(raw, 16, enc, sizeof enc);
    enc[e] = 0;
    dec_log l3 = {0};
    feed(&dec, enc, (size_t)e + 1, 4, &l3);
    assert_int_equal(l3.err[0], IT2N_PROTO_ERR_LENGTH);
    /* Version 1 (v1.0), otherwise fine: VERSION with the header filled in. */
    it2n_frame_hdr h = {1, 1, IT2N_FLAG_REL, 99, 0};
    int w = it2n_frame_encode(&h, NULL, 0, wire, sizeof wire);
    size_t used;
    const uint8_t *p;
    it2n_frame_hdr got;
    it2n_frame_decoder_init(&dec);
    assert_int_equal(it2n_frame_decode(&dec, wire, (size_t)w, &used, &got, &p), IT2N_PROTO_ERR_VERSION);
    assert_int_equal(got.version, 1);
    assert_int_equal(got.seq, 99);
    assert_int_equal(dec.stats.version, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_check_value),
        cmocka_unit_test(test_cobs_edges),
        cmocka_unit_test(test_frame_sizes_and_chunks),
        cmocka_unit_test(test_every_bit_flip_caught),
        cmocka_unit_test(test_truncation_every_offset),
        cmocka_unit_test(test_garbage_between_frames),
        cmocka_unit_test(test_oversize_and_short),
    };
    return cmocka_run_group_tests_name("proto_frame", tests, NULL, NULL);
}
