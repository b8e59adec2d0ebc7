/* Golden vectors: the files in protocol/vectors/ must equal what the
 * encoder produces today, and the freestanding self-test must pass. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "proto_test.h"

static const char *vdir = "protocol/vectors";

static size_t read_hex(const char *path, uint8_t *out, size_t cap)
{
    FILE *f = fopen(path, "r");
    char line[256];
    size_t n = 0;
    if (f == NULL) {
        fail_msg("cannot open %s", path);
        return 0;
    }
    while (fgets(line, sizeof line, f) != NULL) {
        char *s = line;
        if (line[0] == '#')
            continue;
        for (;;) {
            char *end;
            unsigned long v = strtoul(s, &end, 16);
            if (end == s)
                break;
            assert_true(v <= 0xFF && n < cap);
            out[n++] = (uint8_t)v;
            s = end;
        }
    }
    fclose(f);
    return n;
}

static void test_files_match_encoder(void **st)
{
    (void)st;
    for (unsigned k = 0; k < IT2N_VECTOR_COUNT; k++) {
        it2n_frame_hdr h;
        it2n_msg m, back;
        uint8_t payload[IT2N_FRAME_MAX_LEN], wire[IT2N_FRAME_MAX_WIRE], file[IT2N_FRAME_MAX_WIRE];
        char path[512];
        const char *name = it2n_proto_vector(k, &h, &m);
        assert_non_null(name);
        size_t sess = ((h.flags & IT2N_FLAG_SYN) || h.version == IT2N_PROTO_VERSION_12)
                          ? IT2N_FRAME_SESSION_SIZE : 0;
        assert_int_equal(h.version, k >= IT2N_VECTOR_FIRST_V12 ? IT2N_PROTO_VERSION_12 : IT2N_PROTO_VERSION);
        int len = it2n_msg_pack(&m, payload + sess, IT2N_PROTO_MAX_PAYLOAD, NULL);
        assert_true(len >= 0);
        for (size_t b = 0; b < sess; b++)
            payload[b] = (uint8_t)(IT2N_VECTOR_SESSION >> (8 * b));
        len += (int)sess;
        h.len = (uint16_t)len;
        int w = it2n_frame_encode(&h, payload, (size_t)len, wire, sizeof wire);
        assert_true(w > 0);
        snprintf(path, sizeof path, "%s/%02u_%s.hex", vdir, k, name);
        size_t fl = read_hex(path, file, sizeof file);
        if (fl != (size_t)w || memcmp(file, wire, fl) != 0)
            fail_msg("%s differs from the encoder (run `make proto-vectors` only if the wire change is intended)", path);
        /* Parsed back, the message struct is identical to the source. */
        it2n_frame_decoder d;
        it2n_frame_decoder_init(&d);
        size_t used;
        const uint8_t *p;
        it2n_frame_hdr got;
        assert_int_equal(it2n_frame_decode(&d, file, fl, &used, &got, &p), 1);
        assert_int_equal(got.version, h.version);
        assert_int_equal(it2n_msg_unpack(got.type, p + sess, got.len - sess, &back, NULL), IT2N_OK);
        assert_memory_equal(&back.u, &m.u, sizeof m.u);
    }
    assert_null(it2n_proto_vector(IT2N_VECTOR_COUNT, NULL, NULL));
}

static void test_selftest(void **st)
{
    (void)st;
    assert_int_equal(it2n_proto_selftest(), 0);
}

int main(int argc, char **argv)
{
    if (argc > 2)
        vdir = argv[2];
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_files_match_encoder),
        cmocka_unit_test(test_selftest),
    };
    return cmocka_run_group_tests_name("proto_vectors", tests, NULL, NULL);
}
