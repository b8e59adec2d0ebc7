/* Unit tests: message pack/unpack bounds and field checks. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "proto_test.h"

static it2n_msg m, back;
static uint8_t buf[IT2N_PROTO_MAX_PAYLOAD + 8];

static void test_length_must_be_exact(void **st)
{
    (void)st;
    for (unsigned k = 0; k < IT2N_VECTOR_COUNT; k++) {
        it2n_frame_hdr h;
        it2n_proto_vector(k, &h, &m);
        int len = it2n_msg_pack(&m, buf, sizeof buf, NULL);
        assert_true(len > 0);
        assert_int_equal(it2n_msg_unpack(m.type, buf, (size_t)len, &back, NULL), IT2N_OK);
        /* The v1.2 forms of ACK (10 bytes) and GAP (12) begin with the
         * v1.1 form (2 and 4 bytes), a message of its own. */
        int other = m.type == IT2N_MSG_ACK && len == (int)IT2N_ACK12_LEN   ? 2
                    : m.type == IT2N_MSG_GAP && len == (int)IT2N_GAP12_LEN ? 4
                                                                           : -1;
        /* Every other shorter length and one longer is refused as PAYLOAD. */
        for (int cut = 0; cut < len; cut++) {
            it2n_proto_errinfo e;
            int r = it2n_msg_unpack(m.type, buf, (size_t)cut, &back, &e);
            if (cut == other) {
                assert_int_equal(r, IT2N_OK);
                continue;
            }
            /* A shorter variable-length message may fail its count check
             * first (FIELD); it must never be accepted. */
            assert_true(r == IT2N_PROTO_ERR_PAYLOAD || r == IT2N_PROTO_ERR_FIELD);
            assert_int_equal(e.code, r);
            /* v1.1 (issue 11): PAYLOAD says the length found and the one
             * the type requires, once the bytes at hand tell it */
            if (r == IT2N_PROTO_ERR_PAYLOAD) {
                assert_true(e.value == cut);
                int known = !((m.type == IT2N_MSG_PUT && cut < 3) || (m.type == IT2N_MSG_SAMPLE_DATA && cut < 13) ||
                              (m.type == IT2N_MSG_NET_ROW && cut < 6) ||
                              /* v1.3: byte 4 tells a 5-byte CONFIGURE */
                              (m.type == IT2N_MSG_CONFIGURE && cut < 5));
                if (m.type == IT2N_MSG_CONFIGURE && cut < 4)
                    assert_true(e.limit == 4);
                if (known)
                    assert_true(e.limit == len || e.limit == other);
            }
        }
        buf[len] = 0;
        it2n_proto_errinfo e2;
        assert_int_equal(it2n_msg_unpack(m.type, buf, (size_t)len + 1, &back, &e2), IT2N_PROTO_ERR_PAYLOAD);
        assert_true(e2.value == len + 1 && (e2.limit == len || e2.limit == other));
        /* Packing into one byte too few: NOSPACE. */
        assert_int_equal(it2n_msg_pack(&m, buf, (size_t)len - 1, NULL), IT2N_PROTO_ERR_NOSPACE);
    }
}

static void test_unknown_type(void **st)
{
    (void)st;
    it2n_proto_errinfo e;
    assert_int_equal(it2n_msg_unpack(0x7F, buf, 0, &back, &e), IT2N_PROTO_ERR_TYPE);
    assert_int_equal(e.value, 0x7F);
    m.type = 0;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_TYPE);
    assert_null(it2n_msg_name(0x7F));
    assert_string_equal(it2n_msg_name(IT2N_MSG_PUT), "PUT");
}

/* Pack a valid message, patch one payload byte, expect FIELD at offset. */
static void expect_field_at(uint8_t type, size_t off, uint8_t bad, int64_t limit, size_t field)
{
    it2n_frame_hdr h;
    unsigned k;
    for (k = 0; k < IT2N_VECTOR_COUNT; k++) {
        it2n_proto_vector(k, &h, &m);
        if (m.type == type)
            break;
    }
    assert_true(k < IT2N_VECTOR_COUNT);
    int len = it2n_msg_pack(&m, buf, sizeof buf, NULL);
    assert_true(len > (int)off);
    buf[off] = bad;
    it2n_proto_errinfo e;
    int r = it2n_msg_unpack(type, buf, (size_t)len, &back, &e);
    if (r != IT2N_PROTO_ERR_FIELD)
        fail_msg("type 0x%02x off %zu byte 0x%02x: got %d", type, off, bad, r);
    assert_int_equal(e.offset, field);
    assert_int_equal(e.limit, limit);
}

static void expect_field(uint8_t type, size_t off, uint8_t bad, int64_t limit)
{
    expect_field_at(type, off, bad, limit, off);
}

static void test_field_checks(void **st)
{
    (void)st;
    expect_field(IT2N_MSG_CONFIGURE, 0, 0xFF, 0xFE);             /* model ALL */
    expect_field(IT2N_MSG_CONFIGURE, 1, 0, IT2N_MAX_DEGREE);     /* n = 0 */
    expect_field(IT2N_MSG_CONFIGURE, 2, IT2N_MAX_DEGREE + 1, IT2N_MAX_DEGREE);
    expect_field(IT2N_MSG_CONFIGURE, 3, 0x08, IT2N_F_ALL);       /* unknown flag */
    expect_field(IT2N_MSG_PUT, 1, 0x04, IT2N_PUT_FLAGS);         /* unknown flag */
    expect_field(IT2N_MSG_PUT, 2, 0, IT2N_PUT_MAX);              /* count 0 */
    expect_field(IT2N_MSG_PUT, 3, 1, 0);                         /* reserved */
    expect_field(IT2N_MSG_PUT, 7, 0x80, 0);                      /* entry reserved */
    expect_field(IT2N_MSG_PUT, 6, IT2N_FP_COUNT, IT2N_FP_COUNT - 1);     /* fp */
    expect_field(IT2N_MSG_PUT, 4 + 52 + 2, 9, IT2N_FP_COUNT - 1);        /* 2nd fp */
    expect_field_at(IT2N_MSG_QUERY, 4, 0x41, IT2N_WIRE_PAR_ONE, 1); /* u > 1.0 */
    expect_field(IT2N_MSG_SAMPLE, 1, 7, IT2N_FP_COUNT - 1);
    expect_field(IT2N_MSG_SAMPLE, 2, 1, 2);                      /* rows 1 */
    expect_field(IT2N_MSG_EVENT, 1, 0, IT2N_EV_LOST);
    expect_field(IT2N_MSG_EVENT, 1, IT2N_EV_LOST + 1, IT2N_EV_LOST);
    expect_field(IT2N_MSG_HELLO, 3, 0, 1);                       /* window 0 */
    expect_field_at(IT2N_MSG_HELLO, 9, 0, IT2N_HELLO_MIN_PAYLOAD, 8); /* max_payload < 64 */
    expect_field_at(IT2N_MSG_NACK, 3, 0x00, -1, 2);              /* code >= 0 */
    expect_field(IT2N_MSG_NET_ROW, 6, 4, 3);                     /* row > n */
    expect_field(IT2N_MSG_STATUS, 3, 4, IT2N_MS_ERROR);
    expect_field(IT2N_MSG_LOCATE_RESULT, 19 + 8, 3, IT2N_LOC_NOCONV); /* status */
    expect_field(IT2N_MSG_SAMPLE_DATA, 12, 0, IT2N_SAMPLE_MAX);  /* count 0 */
}

static void test_pack_refuses_what_unpack_refuses(void **st)
{
    (void)st;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_CONFIGURE;
    m.u.configure.n = 3;
    m.u.configure.m = 0;
    it2n_proto_errinfo e;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, &e), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(e.offset, 2);
    m.type = IT2N_MSG_PUT;
    m.u.put.count = (uint8_t)(IT2N_PUT_MAX + 1);
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_FIELD);
    m.type = IT2N_MSG_SAMPLE_DATA;
    m.u.sample_data.rows = 2;
    m.u.sample_data.cols = 2;
    m.u.sample_data.start = 3;
    m.u.sample_data.count = 2; /* 3 + 2 > 4 points */
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_FIELD);
}

static void test_max_put_fits(void **st)
{
    (void)st;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_PUT;
    m.u.put.count = IT2N_PUT_MAX;
    for (unsigned k = 0; k < IT2N_PUT_MAX; k++) {
        m.u.put.e[k].i = (uint8_t)(k % (IT2N_MAX_DEGREE + 1));
        m.u.put.e[k].fp = (uint8_t)(k % IT2N_FP_COUNT);
        for (unsigned c = 0; c < IT2N_CH_COUNT; c++)
            m.u.put.e[k].vals[c] = (it2n_val)(k * 1000 + c) * (c % 2 ? -1 : 1) * IT2N_VAL_ONE;
    }
    int len = it2n_msg_pack(&m, buf, sizeof buf, NULL);
    assert_int_equal(len, (int)(IT2N_PUT_HDR + IT2N_PUT_MAX * IT2N_PUT_ENTRY));
    assert_true(len <= IT2N_PROTO_MAX_PAYLOAD);
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_PUT, buf, (size_t)len, &back, NULL), IT2N_OK);
    assert_memory_equal(&back.u.put, &m.u.put, sizeof m.u.put);
    /* Extremes of int64 survive the wire. */
    m.u.put.count = 1;
    m.u.put.e[0].vals[0] = INT64_MIN;
    m.u.put.e[0].vals[1] = INT64_MAX;
    m.u.put.e[0].vals[2] = -1;
    len = it2n_msg_pack(&m, buf, sizeof buf, NULL);
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_PUT, buf, (size_t)len, &back, NULL), IT2N_OK);
    assert_true(back.u.put.e[0].vals[0] == INT64_MIN);
    assert_true(back.u.put.e[0].vals[1] == INT64_MAX);
    assert_true(back.u.put.e[0].vals[2] == -1);
}

/* Vector k's message, packed into buf; returns the length. */
static int pack_vector(unsigned k)
{
    it2n_frame_hdr h;
    assert_non_null(it2n_proto_vector(k, &h, &m));
    return it2n_msg_pack(&m, buf, sizeof buf, NULL);
}

static void expect_cfg(int len, int code, size_t off, int64_t value, int64_t limit)
{
    it2n_proto_errinfo e;
    int r = it2n_msg_unpack(IT2N_MSG_CONFIGURE, buf, (size_t)len, &back, &e);
    if (r != code)
        fail_msg("CONFIGURE %02x %02x %02x %02x %02x (len %d): got %d, want %d", buf[0], buf[1], buf[2],
                 buf[3], buf[4], len, r, code);
    assert_int_equal(e.code, code);
    assert_int_equal(e.offset, off);
    assert_true(e.value == value);
    assert_true(e.limit == limit);
}

/* v1.3 (docs/protocol.md 5.3): the 5-byte CONFIGURE names the kind; the
 * 4-byte one of every older peer is still Bezier; each invalid input gets
 * the documented error. */
static void test_configure_kinds(void **st)
{
    (void)st;
    int len;
    /* vector 01: 4 bytes, a v1.1/v1.2 peer's CONFIGURE: Bezier */
    assert_int_equal(pack_vector(1), 4);
    memset(&back, 0xA5, sizeof back);
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_CONFIGURE, buf, 4, &back, NULL), IT2N_OK);
    assert_int_equal(back.u.configure.kind, IT2N_CFG_BEZIER);
    assert_int_equal(back.u.configure.n, 3);
    /* vector 19: 5 bytes, B-spline 64 x 48 with z, round trip */
    len = pack_vector(19);
    assert_int_equal(len, IT2N_CONFIGURE13_LEN);
    static const uint8_t want[] = {2, 64, 48, IT2N_F_Z, IT2N_CFG_BSPLINE};
    assert_memory_equal(buf, want, sizeof want);
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_CONFIGURE, buf, 5, &back, NULL), IT2N_OK);
    assert_memory_equal(&back.u.configure, &m.u.configure, sizeof m.u.configure);
    /* the largest grid, 256 x 256 points, and the smallest */
    buf[1] = 255, buf[2] = 255;
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_CONFIGURE, buf, 5, &back, NULL), IT2N_OK);
    assert_int_equal(back.u.configure.n, 255);
    buf[1] = 1, buf[2] = 1, buf[3] = IT2N_F_TYPE1 | IT2N_F_Z;
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_CONFIGURE, buf, 5, &back, NULL), IT2N_OK);
    /* its first four bytes alone: a Bezier CONFIGURE (n = 64 > 7: FIELD) */
    pack_vector(19);
    expect_cfg(4, IT2N_PROTO_ERR_FIELD, 1, 64, IT2N_MAX_DEGREE);
    /* kind 0 has only the 4-byte form: 5 bytes are one too many */
    pack_vector(19);
    buf[4] = IT2N_CFG_BEZIER;
    expect_cfg(5, IT2N_PROTO_ERR_PAYLOAD, 4, 5, 4);
    /* an unknown kind */
    buf[4] = 2;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 4, 2, IT2N_CFG_BSPLINE);
    buf[4] = 0xFF;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 4, 0xFF, IT2N_CFG_BSPLINE);
    /* sizes 0 */
    pack_vector(19);
    buf[1] = 0;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 1, 0, 255);
    pack_vector(19);
    buf[2] = 0;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 2, 0, 255);
    /* chord-length parameters: uniform only */
    pack_vector(19);
    buf[3] = IT2N_F_CHORD;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 3, IT2N_F_CHORD, IT2N_F_Z | IT2N_F_TYPE1);
    buf[3] = 0x08;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 3, 0x08, IT2N_F_ALL);
    /* model 255 (all) is RESET's only; checked first */
    pack_vector(19);
    buf[0] = 0xFF;
    buf[4] = 7;
    expect_cfg(5, IT2N_PROTO_ERR_FIELD, 0, 0xFF, 0xFE);
    /* 6 bytes: PAYLOAD, the type needs 5 */
    pack_vector(19);
    buf[5] = 0;
    expect_cfg(6, IT2N_PROTO_ERR_PAYLOAD, 5, 6, 5);
    buf[4] = IT2N_CFG_BEZIER; /* ... and with kind 0, a Bezier one too long */
    expect_cfg(6, IT2N_PROTO_ERR_PAYLOAD, 4, 6, 4);
    /* pack validates as unpack: a bad kind, CHORD, n = 0 are never sent */
    it2n_proto_vector(19, &(it2n_frame_hdr){0}, &m);
    m.u.configure.kind = 2;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_FIELD);
    m.u.configure.kind = IT2N_CFG_BSPLINE;
    m.u.configure.flags = IT2N_F_CHORD;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_FIELD);
    m.u.configure.flags = 0;
    m.u.configure.m = 0;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_FIELD);
    /* Bezier sizes beyond 7 are still refused in the 4-byte form */
    m.u.configure.kind = IT2N_CFG_BEZIER;
    m.u.configure.m = IT2N_MAX_DEGREE + 1;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, NULL), IT2N_PROTO_ERR_FIELD);
}

/* v1.3: PUT indices 0..255 (the server bounds them by the model's n, m). */
static void test_put_indices_255(void **st)
{
    (void)st;
    int len = pack_vector(2);
    buf[4] = 255;     /* i of entry 0 */
    buf[5] = 200;     /* j */
    buf[4 + 52] = 8;  /* i of entry 1: beyond a Bezier degree */
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_PUT, buf, (size_t)len, &back, NULL), IT2N_OK);
    assert_int_equal(back.u.put.e[0].i, 255);
    assert_int_equal(back.u.put.e[0].j, 200);
    assert_int_equal(back.u.put.e[1].i, 8);
    assert_int_equal(it2n_msg_pack(&back, buf + 512, 512, NULL), len);
    assert_memory_equal(buf, buf + 512, (size_t)len);
}

/* v1.3 PUT FINE (docs/protocol.md 5.4): flag 0x02, memberships in Q30
 * carried bit for bit; every invalid input gets its error in the order of
 * the table; pack refuses what unpack refuses. */
static void expect_put(int len, int code, size_t off, int64_t value, int64_t limit)
{
    it2n_proto_errinfo e;
    int r = it2n_msg_unpack(IT2N_MSG_PUT, buf, (size_t)len, &back, &e);
    if (r != code)
        fail_msg("PUT %02x %02x %02x %02x (len %d): got %d, want %d", buf[0], buf[1], buf[2], buf[3], len,
                 r, code);
    assert_int_equal(e.offset, off);
    assert_int_equal(e.value, value);
    assert_int_equal(e.limit, limit);
}

static void test_put_fine(void **st)
{
    (void)st;
    it2n_proto_errinfo e;
    int len = pack_vector(23);
    assert_int_equal(IT2N_PUT_FINE, 0x02);
    assert_int_equal(IT2N_CAP_FINE, 0x80);
    assert_int_equal(len, 4 + 2 * 52);
    assert_int_equal(buf[1], IT2N_PUT_FINE);
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_PUT, buf, (size_t)len, &back, NULL), IT2N_OK);
    assert_int_equal(back.u.put.flags, IT2N_PUT_FINE);
    /* Q30, finer than Q24: carried bit for bit */
    assert_true(back.u.put.e[0].vals[IT2N_CH_T] == 966367642);
    assert_true(back.u.put.e[0].vals[IT2N_CH_T] % 64 != 0);
    assert_true(back.u.put.e[1].vals[IT2N_CH_T] == IT2N_MEMB_ONE);
    assert_int_equal(back.u.put.e[0].i, 200);
    /* REPLACE | FINE */
    buf[1] = IT2N_PUT_REPLACE | IT2N_PUT_FINE;
    assert_int_equal(it2n_msg_unpack(IT2N_MSG_PUT, buf, (size_t)len, &back, NULL), IT2N_OK);
    assert_int_equal(back.u.put.flags, 3);
    assert_int_equal(it2n_msg_pack(&back, buf + 512, 512, NULL), len);
    assert_memory_equal(buf, buf + 512, (size_t)len);
    /* order of checks: model 255, then (before the flags) reserved byte 3 */
    buf[0] = 0xFF;
    buf[1] = 0x80;
    buf[3] = 1;
    expect_put(len, IT2N_PROTO_ERR_FIELD, 0, 0xFF, 0xFE);
    expect_put(2, IT2N_PROTO_ERR_FIELD, 0, 0xFF, 0xFE); /* even when short */
    buf[0] = 2;
    expect_put(2, IT2N_PROTO_ERR_PAYLOAD, 2, 2, 3);     /* shorter than 4 */
    expect_put(len, IT2N_PROTO_ERR_FIELD, 3, 1, 0);
    buf[3] = 0;
    /* every flag bit beyond REPLACE | FINE: FIELD at 1, hi = 3 */
    for (unsigned f = 4; f < 256; f += 4) {
        buf[1] = (uint8_t)(f | IT2N_PUT_FINE);
        expect_put(len, IT2N_PROTO_ERR_FIELD, 1, (int64_t)(f | IT2N_PUT_FINE), IT2N_PUT_FLAGS);
    }
    buf[1] = IT2N_PUT_FINE;
    buf[2] = 0;
    expect_put(len, IT2N_PROTO_ERR_FIELD, 2, 0, IT2N_PUT_MAX); /* count 0 */
    buf[2] = 3;
    expect_put(len, IT2N_PROTO_ERR_PAYLOAD, (size_t)len, len, 4 + 3 * 52); /* truncated */
    buf[2] = 2;
    expect_put(len - 1, IT2N_PROTO_ERR_PAYLOAD, (size_t)len - 8, len - 1, len);
    /* pack refuses a flag unpack refuses, and nothing beyond */
    assert_non_null(it2n_proto_vector(23, &(it2n_frame_hdr){0}, &m));
    m.u.put.flags = 0x04 | IT2N_PUT_FINE;
    assert_int_equal(it2n_msg_pack(&m, buf, sizeof buf, &e), IT2N_PROTO_ERR_FIELD);
    assert_int_equal(e.offset, 1);
    assert_int_equal(e.limit, IT2N_PUT_FLAGS);
}

static void test_par_conversion(void **st)
{
    (void)st;
    assert_int_equal(it2n_par_to_wire(0), 0);
    assert_int_equal(it2n_par_to_wire(IT2N_PAR_ONE), IT2N_WIRE_PAR_ONE);
    assert_int_equal(it2n_par_to_wire(IT2N_PAR_ONE / 2), IT2N_WIRE_PAR_ONE / 2);
    assert_int_equal(it2n_par_to_wire(-5), 0);
    assert_int_equal(it2n_par_to_wire(IT2N_PAR_ONE + 9), IT2N_WIRE_PAR_ONE);
    assert_int_equal(it2n_par_to_wire(6), 2); /* rounds to nearest */
    assert_true(it2n_par_from_wire(IT2N_WIRE_PAR_ONE) == IT2N_PAR_ONE);
    assert_true(it2n_par_from_wire(1) == 4);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_length_must_be_exact),
        cmocka_unit_test(test_unknown_type),
        cmocka_unit_test(test_field_checks),
        cmocka_unit_test(test_pack_refuses_what_unpack_refuses),
        cmocka_unit_test(test_max_put_fits),
        cmocka_unit_test(test_par_conversion),
        cmocka_unit_test(test_configure_kinds),
        cmocka_unit_test(test_put_indices_255),
        cmocka_unit_test(test_put_fine),
    };
    return cmocka_run_group_tests_name("proto_msg", tests, NULL, NULL);
}
