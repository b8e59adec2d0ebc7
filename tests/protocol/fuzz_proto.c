/*
 * Fuzz target: streaming frame decoder + message parser + link receiver.
 * Invariants checked (abort on violation): the decoder consumes input and
 * never reports a frame longer than the maximum; whatever unpacks packs
 * back to the identical payload; the link survives anything.
 *
 * clang -fsanitize=fuzzer,...: libFuzzer entry point (make proto-fuzz).
 * -DIT2N_FUZZ_MAIN: plain program running every file of a corpus directory
 * plus seeded mutations of each (make test, gcc, with and without ASan).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "it2n_link.h"

static uint32_t fuzz_session(void *app)
{
    static uint32_t n; /* the fuzzer's own state, not the library's */
    (void)app;
    return 0x5E550000u + ++n;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "fuzz_proto: invariant broken: %s\n", what);
        abort();
    }
}

static void roundtrip(uint8_t type, const uint8_t *p, size_t len)
{
    static it2n_msg m;
    static uint8_t again[IT2N_PROTO_MAX_PAYLOAD];
    it2n_proto_errinfo e;
    int r = it2n_msg_unpack(type, p, len, &m, &e);
    if (r != IT2N_OK) {
        check(r == e.code && r <= IT2N_PROTO_ERR_TYPE && r >= IT2N_PROTO_ERR_FIELD, "unpack error code");
        check(e.offset <= len, "error offset inside payload");
        return;
    }
    int n = it2n_msg_pack(&m, again, sizeof again, NULL);
    check(n >= 0 && (size_t)n == len && memcmp(again, p, len) == 0, "unpack/pack round trip");
}

static int sink_write(it2n_ostream *s, const uint8_t *b, size_t n)
{
    (void)s, (void)b;
    check(n >= 1 && n <= 255, "ostream block size contract");
    return 0;
}

static int rx_any(void *app, uint16_t seq, const it2n_msg *m)
{
    (void)app, (void)seq;
    check(it2n_msg_name(m->type) != NULL, "delivered message has a known type");
    return (seq & 1u) ? IT2N_LINK_DEFER : 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static it2n_frame_decoder dec;
    static it2n_link link;
    static it2n_ostream os = {sink_write, NULL};
    size_t chunk = size > 0 ? (size_t)(data[0] % 17u) + 1u : 1u;
    size_t pos = 0;

    /* 1: decoder + parser, input split into chunks. */
    it2n_frame_decoder_init(&dec);
    while (pos < size) {
        size_t n = size - pos < chunk ? size - pos : chunk;
        while (n > 0) {
            it2n_frame_hdr h;
            const uint8_t *p = NULL;
            size_t used = 0;
            int r = it2n_frame_decode(&dec, data + pos, n, &used, &h, &p);
            check(used >= 1 && used <= n, "decoder consumes input");
            if (r == 1) {
                check(h.len <= IT2N_PROTO_MAX_PAYLOAD && p != NULL, "frame bounds");
                roundtrip(h.type, p, h.len);
            } else {
                check(r <= 0 && r >= IT2N_PROTO_ERR_VERSION, "decoder result");
            }
            pos += used;
            n -= used;
        }
    }
    /* 2: the raw bytes as a payload of the type in byte 0. */
    if (size > 0 && size - 1 <= IT2N_PROTO_MAX_PAYLOAD)
        roundtrip(data[0], data + 1, size - 1);
    /* 3: the link receiver on the same bytes. */
    it2n_link_cfg cfg = {&os, NULL, rx_any, NULL, NULL, 10, 3, 0, 0x600D5E55u, 0, 0, 0, 0, NULL};
    check(it2n_link_init(&link, &cfg) == IT2N_OK, "link init");
    /* One frame in flight so injected ACK/NACK (NOSYNC...) hit a sender. */
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_COMMIT;
    check(it2n_link_send(&link, &m, 0) == 0, "first send gets seq 0");
    check(it2n_link_input(&link, data, size, 0) == IT2N_OK, "link input");
    check(it2n_link_pending(&link) <= IT2N_PROTO_WINDOW, "window bound");
    (void)it2n_link_poll(&link, 5);
    (void)it2n_link_poll(&link, 50);
    for (uint16_t s = 0; s < 8; s++)
        (void)it2n_link_complete(&link, s, s & 2 ? 0 : IT2N_ERR_RANGE, NULL);
    /* 4: the same bytes into a v1.2 server (session field on every frame,
     * sessions handed out) and a v1.2 client waiting for its session. */
    it2n_link_cfg sc = {&os, NULL, rx_any, NULL, NULL, 10, 3, 0, 0x600D5E55u, 0, 0, 0, 0, fuzz_session};
    check(it2n_link_init(&link, &sc) == IT2N_OK, "v1.2 server init");
    check(it2n_link_input(&link, data, size, 0) == IT2N_OK, "v1.2 server input");
    check(it2n_link_pending(&link) <= IT2N_PROTO_WINDOW, "v1.2 server window bound");
    (void)it2n_link_poll(&link, 50);
    it2n_link_cfg cc = {&os, NULL, rx_any, NULL, NULL, 10, 3, 0, 0, 0, 0, 0, IT2N_PROTO_VERSION_12, NULL};
    check(it2n_link_init(&link, &cc) == IT2N_OK, "v1.2 client init");
    m.type = IT2N_MSG_HELLO;
    m.u.hello.version_min = m.u.hello.version_max = IT2N_PROTO_VERSION_12;
    m.u.hello.window = 4;
    m.u.hello.max_payload = 64;
    check(it2n_link_send(&link, &m, 0) == 0, "v1.2 HELLO asks for a session");
    check(it2n_link_input(&link, data, size, 0) == IT2N_OK, "v1.2 client input");
    check(it2n_link_pending(&link) <= IT2N_PROTO_WINDOW + 1u, "v1.2 client window bound");
    (void)it2n_link_poll(&link, 50);
    (void)it2n_link_poll(&link, 500);
    return 0;
}

#ifdef IT2N_FUZZ_MAIN
#include <dirent.h>

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static uint64_t rnd(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 0x2545F4914F6CDD1Dull;
}

int main(int argc, char **argv)
{
    static uint8_t buf[1 << 16], mut[1 << 16];
    const char *dir = argc > 1 ? argv[1] : "tests/protocol/corpus";
    char path[4096];
    unsigned files = 0, runs = 0;
    DIR *d = opendir(dir);
    struct dirent *de;

    if (d == NULL) {
        perror(dir);
        return 1;
    }
    while ((de = readdir(d)) != NULL) {
        if (de->d_name[0] == '.')
            continue;
        snprintf(path, sizeof path, "%s/%s", dir, de->d_name);
        FILE *f = fopen(path, "rb");
        if (f == NULL)
            continue;
        size_t n = fread(buf, 1, sizeof buf, f);
        fclose(f);
        files++;
        LLVMFuzzerTestOneInput(buf, n);
        runs++;
        /* Deterministic mutations: flips, truncations, splices. */
        for (int k = 0; k < 300; k++) {
            size_t m = n;
            memcpy(mut, buf, n);
            unsigned ops = 1 + (unsigned)(rnd() % 4);
            for (unsigned o = 0; o < ops && m > 0; o++) {
                switch (rnd() % 4) {
                case 0: mut[rnd() % m] ^= (uint8_t)(1u << (rnd() % 8)); break;
                case 1: mut[rnd() % m] = (uint8_t)rnd(); break;
                case 2: m = (size_t)(rnd() % m); break;
                default:
                    if (m < sizeof mut / 2) { memcpy(mut + m, mut, m); m *= 2; }
                    break;
                }
            }
            LLVMFuzzerTestOneInput(mut, m);
            runs++;
        }
    }
    closedir(d);
    printf("fuzz_proto: %u corpus files, %u runs, all invariants held\n", files, runs);
    return files > 0 ? 0 : 1;
}
#endif
