/* test_links — the daemon's link output on a full tty (security finding
 * 7). links.c runs on the real loop with a serial link on a pty; the test
 * is the instrument on the master side and reads slowly:
 *
 *  1. it floods the link with reliable frames before any SYN (each is
 *     answered at once with a NACK NOSYNC) and does not read, so the pty
 *     (about 22 KiB) fills: the daemon must arm POLLOUT, never block, and
 *     drop only whole frames when its own queue is full;
 *  2. then it asks for a 40 x 40 SAMPLE run and reads in dribbles of 256
 *     bytes with pauses. Every byte the daemon wrote must decode as intact
 *     frames (no CRC, COBS, oversize or length errors), every NOSYNC frame
 *     was answered or its answer dropped whole (counted), and every node of
 *     the SAMPLE run arrives with the value of a fresh it2n_eval.
 * Before the fix os_write dropped a COBS block on EAGAIN and sent the rest,
 * so step 2 saw corrupt or merged frames. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>
#include <errno.h>
#include <fcntl.h>
#include <pty.h>
#include <unistd.h>

#include "conf.h"
#include "it2n_link.h"
#include "links.h"
#include "loop.h"
#include "models.h"

#define FLOOD 2000u
#define ROWS 40u
#define COLS 40u

static int master = -1, slave = -1;
static struct conf cf;

/* ---- the instrument's side ---- */
static it2n_link peer;
static it2n_ostream peer_os;
static uint8_t seen[ROWS * COLS];
static unsigned nodes, dup_nodes, bad_nodes;

static void write_all(const uint8_t *p, size_t n)
{
    while (n) {
        ssize_t w = write(master, p, n);
        if (w < 0 && (errno == EAGAIN || errno == EINTR)) {
            loop_run_once(1); /* the daemon reads: room frees */
            continue;
        }
        assert_true(w > 0);
        p += w;
        n -= (size_t)w;
    }
}

static int peer_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    (void)s;
    write_all(buf, len);
    return 0;
}

static int peer_rx(void *app, uint16_t seq, const it2n_msg *msg)
{
    (void)app;
    (void)seq;
    if (msg->type != IT2N_MSG_SAMPLE_DATA)
        return 0; /* EVENTs, HELLO: ACK */
    const it2n_msg_sample_data *d = &msg->u.sample_data;
    const struct model *md = models_by_id(1);
    for (unsigned k = 0; k < d->count; k++) {
        uint32_t idx = d->start + k, r = idx / COLS, c = idx % COLS;
        it2n_point pt;
        it2n_par u = (it2n_par)(((uint64_t)r << IT2N_PAR_FRAC) / (ROWS - 1u));
        it2n_par w = (it2n_par)(((uint64_t)c << IT2N_PAR_FRAC) / (COLS - 1u));
        if (idx >= ROWS * COLS || it2n_eval(&md->mdl, u, w, &pt, NULL) != IT2N_OK ||
            memcmp(d->v[k], pt.v[IT2N_FP_D], sizeof d->v[k]) != 0) {
            bad_nodes++;
            continue;
        }
        if (seen[idx]++)
            dup_nodes++;
        else
            nodes++;
    }
    return 0;
}

static int setup(void **st)
{
    char name[64];
    (void)st;
    assert_int_equal(models_init(4), 0);
    struct model *md = models_add(1, 1, MODEL_BEZIER, 3, 3, 0);
    assert_non_null(md);
    assert_int_equal(models_preload_paper(md), IT2N_OK);
    assert_int_equal(md->state, IT2N_REGMAP_STATE_SOLVED);
    /* slave stays open here too, so the pty never hangs up. */
    assert_int_equal(openpty(&master, &slave, name, NULL, NULL), 0);
    assert_int_equal(fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK), 0);
    memset(&cf, 0, sizeof cf);
    cf.nlinks = 1;
    cf.link_backoff_max = 1;
    snprintf(cf.link[0].name, sizeof cf.link[0].name, "slow");
    snprintf(cf.link[0].device, sizeof cf.link[0].device, "%s", name);
    cf.link[0].type = CONF_LINK_SERIAL;
    cf.link[0].baud = 115200;
    assert_int_equal(links_start(&cf), 0);
    assert_int_equal(links_up(), 1);
    return 0;
}

static int teardown(void **st)
{
    (void)st;
    links_stop();
    loop_free();
    models_free();
    close(master);
    close(slave);
    return 0;
}

static void test_slow_reader(void **st)
{
    static uint8_t flood[FLOOD * 32];
    static it2n_frame_decoder dec;
    struct links_out_stats os;
    size_t flen = 0;
    unsigned nosync = 0, others = 0, flood_dropped;
    (void)st;

    /* 1. Reliable frames without SYN, not read: NACK NOSYNC each. */
    for (unsigned k = 0; k < FLOOD; k++) {
        uint8_t pl[1] = { 1 };
        it2n_frame_hdr h = { IT2N_PROTO_VERSION, IT2N_MSG_GET_STATUS, IT2N_FLAG_REL, (uint16_t)k, 1 };
        int w = it2n_frame_encode(&h, pl, sizeof pl, flood + flen, sizeof flood - flen);
        assert_true(w > 0);
        flen += (size_t)w;
    }
    write_all(flood, flen);
    for (int k = 0; k < 50; k++)
        loop_run_once(2);
    assert_int_equal(links_out_stats(0, &os), 0);
    print_message("flood: %u frames, %u dropped whole, tty full %u times\n", os.frames, os.dropped, os.blocked);
    assert_int_equal(os.frames, FLOOD);
    assert_true(os.blocked > 0); /* the pty did fill: the case under test */
    assert_true(os.dropped > 0); /* and so did the daemon's queue */
    assert_int_equal(links_up(), 1);
    flood_dropped = os.dropped;

    /* 2. A SAMPLE run, read in dribbles. */
    it2n_link_cfg pc;
    memset(&pc, 0, sizeof pc);
    peer_os.write = peer_write;
    pc.out = &peer_os;
    pc.on_rx = peer_rx;
    pc.rto_ms = 200;
    pc.max_tries = 50;
    pc.first_seq = 40000;
    assert_int_equal(it2n_link_init(&peer, &pc), IT2N_OK);
    it2n_msg m;
    memset(&m, 0, sizeof m);
    m.type = IT2N_MSG_SAMPLE;
    m.u.sample.model = 1;
    m.u.sample.fp = IT2N_FP_D;
    m.u.sample.rows = ROWS;
    m.u.sample.cols = COLS;
    assert_true(it2n_link_send(&peer, &m, (uint32_t)loop_now_ms()) >= 0);

    it2n_frame_decoder_init(&dec);
    uint64_t end = loop_now_ms() + 20000;
    for (unsigned it = 0; loop_now_ms() < end; it++) {
        uint8_t buf[256];
        loop_run_once(1);
        if (it % 3)
            continue; /* the reader pauses */
        ssize_t n = read(master, buf, sizeof buf);
        if (n <= 0) {
            assert_true(n < 0 && errno == EAGAIN);
            it2n_link_poll(&peer, (uint32_t)loop_now_ms());
            if (nodes == ROWS * COLS && it2n_link_pending(&peer) == 0)
                break;
            continue;
        }
        /* Check every frame the daemon wrote ... */
        const uint8_t *p = buf;
        size_t left = (size_t)n;
        while (left) {
            it2n_frame_hdr h;
            const uint8_t *pl = NULL;
            size_t used = 0;
            int r = it2n_frame_decode(&dec, p, left, &used, &h, &pl);
            assert_true(r >= 0);
            p += used;
            left -= used;
            if (r != 1)
                continue;
            it2n_msg got;
            size_t sess = (h.flags & IT2N_FLAG_SYN) ? IT2N_FRAME_SESSION_SIZE : 0; /* v1.1 */
            assert_int_equal(it2n_msg_unpack(h.type, pl + sess, h.len - sess, &got, NULL), IT2N_OK);
            if (got.type == IT2N_MSG_NACK && got.u.nack.code == IT2N_PROTO_ERR_NOSYNC)
                nosync++;
            else
                others++;
        }
        /* ... and let the instrument act on them (ACKs, SAMPLE_DATA). */
        assert_int_equal(it2n_link_input(&peer, buf, (size_t)n, (uint32_t)loop_now_ms()), IT2N_OK);
    }
    /* The rest: the daemon's last frames (ACKs of our ACKs never come:
     * nothing is in flight once every node is in). */
    for (int k = 0; k < 20; k++) {
        uint8_t buf[4096];
        loop_run_once(5);
        ssize_t n = read(master, buf, sizeof buf);
        if (n <= 0)
            continue;
        const uint8_t *p = buf;
        size_t left = (size_t)n;
        while (left) {
            it2n_frame_hdr h;
            const uint8_t *pl = NULL;
            size_t used = 0;
            int r = it2n_frame_decode(&dec, p, left, &used, &h, &pl);
            assert_true(r >= 0);
            p += used;
            left -= used;
            if (r == 1)
                others++;
        }
        assert_int_equal(it2n_link_input(&peer, buf, (size_t)n, (uint32_t)loop_now_ms()), IT2N_OK);
    }
    assert_int_equal(links_out_stats(0, &os), 0);
    print_message("read: %u NOSYNC NACKs, %u other frames; daemon: %u frames, %u dropped, tty full %u times; "
                  "%u nodes\n",
                  nosync, others, os.frames, os.dropped, os.blocked, nodes);
    assert_int_equal(dec.stats.crc + dec.stats.cobs + dec.stats.oversize + dec.stats.shortf + dec.stats.length, 0);
    /* Every NOSYNC frame was answered, or its answer dropped whole. */
    assert_int_equal(nosync, FLOOD - flood_dropped);
    assert_int_equal(nosync + others + os.dropped, os.frames);
    assert_int_equal(bad_nodes, 0);
    assert_int_equal(nodes, ROWS * COLS);
    assert_int_equal(links_up(), 1);
}

/* The RTO default docs/daemon.md states for [link:] (rto_ms): 20 ms + the
 * time one maximum frame takes at the baud rate, counted from when the
 * frame has left the line; the key overrides it. And
 * the keys parse, with their limits. */
static void test_rto_default(void **st)
{
    struct conf_link c;
    (void)st;
    memset(&c, 0, sizeof c);
    c.type = CONF_LINK_SERIAL;
    c.baud = 921600;
    assert_int_equal(links_rto_ms(&c), 32);
    c.baud = 115200;
    assert_int_equal(links_rto_ms(&c), 111);
    c.baud = 9600;
    assert_int_equal(links_rto_ms(&c), 1110);
    c.rto_ms = 30;
    assert_int_equal(links_rto_ms(&c), 30);
    c.rto_ms = 0;
    c.type = CONF_LINK_USB;
    assert_int_equal(links_rto_ms(&c), 100);
    FILE *f = fopen("/tmp/it2n-test-links-rto.conf", "w");
    assert_non_null(f);
    fprintf(f, "[link:a]\ndevice = /dev/null\nrto_ms = 25\npeer_timeout_ms = 800\n");
    fclose(f);
    struct conf *cf2 = calloc(1, sizeof *cf2);
    char err[256];
    assert_non_null(cf2);
    conf_default(cf2); /* as it2nd does before loading a file */
    assert_int_equal(conf_load(cf2, "/tmp/it2n-test-links-rto.conf", err, sizeof err), 0);
    assert_int_equal(cf2->link[0].rto_ms, 25);
    assert_int_equal(cf2->link[0].peer_timeout_ms, 800);
    f = fopen("/tmp/it2n-test-links-rto.conf", "w");
    fprintf(f, "[link:a]\ndevice = /dev/null\nrto_ms = 0\n");
    fclose(f);
    assert_int_not_equal(conf_load(cf2, "/tmp/it2n-test-links-rto.conf", err, sizeof err), 0);
    assert_non_null(strstr(err, "rto_ms"));
    free(cf2);
    unlink("/tmp/it2n-test-links-rto.conf");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_slow_reader, setup, teardown),
        cmocka_unit_test(test_rto_default),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
