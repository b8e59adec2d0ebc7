/*
 * End to end over a real pseudo-terminal: runs the example instrument
 * (it2n-instrument --device /dev/pts/N) against a receiver built from the
 * link library and the core, which drops frames in both directions. The
 * receiver puts every PUT entry into an it2n_dataset without `replace`, so
 * a duplicate application would fail (IT2N_ERR_DUPLICATE) and the run with
 * it; at COMMIT it solves the model. Also checks NACK reporting and the
 * one-way stdout mode.
 * Usage: test_instrument PATH/TO/it2n-instrument
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "proto_test.h"
#include "synth.h"

static const char *instrument = "build/host/it2n-instrument";

typedef struct rx {
    it2n_link l;
    int fd;
    uint64_t rng;
    unsigned drop_in_pct, drop_out_pct, dropped_in, dropped_out, nin, nout;
    uint8_t out[IT2N_FRAME_MAX_WIRE + 8];
    size_t outlen;
    uint8_t in[IT2N_FRAME_MAX_WIRE + 8];
    size_t inlen;
    it2n_dataset ds;
    it2n_model mdl;
    int configured, committed, solve_rc, nack_first_put, puts;
    unsigned hello;
} rx;

static int out_write(it2n_ostream *s, const uint8_t *b, size_t n)
{
    rx *r = s->state;
    for (size_t k = 0; k < n; k++) {
        if (r->outlen < sizeof r->out)
            r->out[r->outlen++] = b[k];
        if (b[k] != 0)
            continue;
        r->nout++; /* frames 2 and 5 always lost when dropping is on */
        if (r->drop_out_pct && (r->nout == 2 || r->nout == 5 ||
                                rng_below(&r->rng, 100) < r->drop_out_pct)) {
            r->dropped_out++;
        } else {
            size_t off = 0;
            while (off < r->outlen) {
                ssize_t w = write(r->fd, r->out + off, r->outlen - off);
                if (w < 0 && errno == EAGAIN)
                    continue;
                assert_true(w > 0);
                off += (size_t)w;
            }
        }
        r->outlen = 0;
    }
    return 0;
}

static uint32_t now_ms(void);

/* v1.2 session ids this receiver hands out */
static uint32_t new_session(void *app)
{
    (void)app;
    return 0x5E55u + (uint32_t)rand();
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    rx *r = app;
    it2n_errinfo e;
    int rc = IT2N_OK;
    memset(&e, 0, sizeof e);
    switch (m->type) {
    case IT2N_MSG_HELLO:
        r->hello++;
        if (r->l.rx_ver == IT2N_PROTO_VERSION_12) {
            /* v1.2: answer with our HELLO, which carries the session id */
            it2n_msg h;
            assert_int_equal(m->u.hello.version_max, IT2N_PROTO_VERSION_12);
            assert_int_equal(it2n_link_complete(&r->l, seq, 0, NULL), IT2N_OK);
            memset(&h, 0, sizeof h);
            h.type = IT2N_MSG_HELLO;
            h.u.hello.version_min = IT2N_PROTO_VERSION;
            h.u.hello.version_max = IT2N_PROTO_VERSION_12;
            h.u.hello.window = 4;
            h.u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
            h.u.hello.caps = IT2N_CAP_SERVER;
            assert_true(it2n_link_send(&r->l, &h, now_ms()) >= 0);
            return IT2N_LINK_DEFER;
        }
        assert_int_equal(m->u.hello.version_max, IT2N_PROTO_VERSION); /* one-way: v1.1 */
        break;
    case IT2N_MSG_CONFIGURE:
        rc = it2n_dataset_init(&r->ds, m->u.configure.n, m->u.configure.m, m->u.configure.flags, &e);
        r->configured++;
        break;
    case IT2N_MSG_PUT:
        if (r->nack_first_put) {
            e.code = rc = IT2N_ERR_RANGE;
            e.i = 1, e.j = 2, e.fp = IT2N_FP_RL, e.ch = IT2N_CH_F;
            break;
        }
        r->puts++;
        for (unsigned k = 0; k < m->u.put.count && rc == IT2N_OK; k++) {
            const it2n_put_entry *p = &m->u.put.e[k];
            rc = it2n_dataset_put(&r->ds, p->i, p->j, p->fp, p->vals, false, &e);
        }
        break;
    case IT2N_MSG_COMMIT:
        rc = r->solve_rc = it2n_model_solve(&r->mdl, &r->ds, &e);
        r->committed++;
        break;
    default:
        fail_msg("unexpected message %s", it2n_msg_name(m->type));
    }
    /* Answer through it2n_link_complete (with the core's detail), as the
     * daemon does after fsync; DEFER tells the link not to answer itself. */
    assert_int_equal(it2n_link_complete(&r->l, seq, rc, rc ? &e : NULL), IT2N_OK);
    return IT2N_LINK_DEFER;
}

static uint32_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u);
}

/* Run the instrument on a pty with `args`; returns its exit status. */
static int run_pty(rx *r, const char *const *args, unsigned nargs)
{
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    assert_true(master >= 0);
    assert_int_equal(grantpt(master), 0);
    assert_int_equal(unlockpt(master), 0);
    char slave[128];
    assert_int_equal(ptsname_r(master, slave, sizeof slave), 0);
    int sfd = open(slave, O_RDWR | O_NOCTTY); /* keep it raw and alive */
    struct termios t;
    assert_int_equal(tcgetattr(sfd, &t), 0);
    cfmakeraw(&t);
    assert_int_equal(tcsetattr(sfd, TCSANOW, &t), 0);
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);

    const char *argv[24] = {instrument, "--device", slave, "--quiet"};
    unsigned argc = 4;
    for (unsigned k = 0; k < nargs && argc < 23; k++)
        argv[argc++] = args[k];
    argv[argc] = NULL;
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        execv(instrument, (char *const *)argv);
        _exit(127);
    }
    r->fd = master;
    it2n_ostream os = {out_write, r};
    it2n_link_cfg cfg = {&os, NULL, on_rx, NULL, r, 50, 10, 0, 0xDAE40001u, 0, 0, 0, 0, new_session};
    assert_int_equal(it2n_link_init(&r->l, &cfg), IT2N_OK);
    uint32_t t0 = now_ms();
    int status = -1;
    for (;;) {
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid)
            break;
        if (now_ms() - t0 > 30000) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            fail_msg("instrument did not finish in 30 s");
        }
        struct pollfd p = {master, POLLIN, 0};
        poll(&p, 1, 10);
        uint8_t buf[256];
        ssize_t n = read(master, buf, sizeof buf);
        for (ssize_t k = 0; k < n; k++) { /* per-frame drop decision */
            if (r->inlen < sizeof r->in)
                r->in[r->inlen++] = buf[k];
            if (buf[k] != 0)
                continue;
            r->nin++;
            if (r->drop_in_pct && (r->nin == 2 || r->nin == 5 ||
                                   rng_below(&r->rng, 100) < r->drop_in_pct))
                r->dropped_in++;
            else
                it2n_link_input(&r->l, r->in, r->inlen, now_ms());
            r->inlen = 0;
        }
        it2n_link_poll(&r->l, now_ms());
    }
    close(sfd);
    close(master);
    assert_true(WIFEXITED(status));
    return WEXITSTATUS(status);
}

static void expect_dataset(const rx *r, unsigned n, unsigned m, unsigned flags, uint32_t seed)
{
    static it2n_dataset want;
    it2n_errinfo e;
    assert_int_equal(synth_dataset(&want, n, m, flags, seed, &e), IT2N_OK);
    assert_int_equal(r->ds.n, n);
    assert_int_equal(r->ds.m, m);
    assert_int_equal(r->ds.flags, flags);
    assert_memory_equal(r->ds.present, want.present, sizeof want.present);
    for (unsigned i = 0; i < IT2N_DIM; i++)
        for (unsigned j = 0; j < IT2N_DIM; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val got[IT2N_CH_COUNT], exp[IT2N_CH_COUNT];
                it2n_dataset_get(&r->ds, i, j, fp, got);
                it2n_dataset_get(&want, i, j, fp, exp);
                assert_memory_equal(got, exp, sizeof exp);
            }
}

static void test_lossy_pty(void **st)
{
    (void)st;
    static rx r;
    memset(&r, 0, sizeof r);
    r.rng = 77;
    r.drop_in_pct = 15;
    r.drop_out_pct = 15;
    const char *args[] = {"--degree", "7x6", "--seed", "9", "--z", "--rto", "40", "--tries", "40"};
    assert_int_equal(run_pty(&r, args, 9), 0);
    assert_true(r.hello >= 1);
    assert_int_equal(r.configured, 1);
    assert_int_equal(r.committed, 1);
    assert_int_equal(r.solve_rc, IT2N_OK);
    expect_dataset(&r, 7, 6, IT2N_F_Z, 9);
    assert_int_equal(it2n_dataset_missing(&r.ds), 0);
    assert_true(r.mdl.solved);
    printf("lossy pty: %d PUTs, dropped %u in / %u out, %u duplicates re-ACKed\n",
           r.puts, r.dropped_in, r.dropped_out, r.l.stats.rx_dup);
    assert_true(r.dropped_in > 0 && r.dropped_out > 0);
}

static void test_nack_is_reported(void **st)
{
    (void)st;
    static rx r;
    memset(&r, 0, sizeof r);
    r.rng = 5;
    r.nack_first_put = 1;
    const char *args[] = {"--degree", "2", "--rto", "40"};
    assert_int_equal(run_pty(&r, args, 4), 1);
    assert_int_equal(r.committed, 0);
}

static void test_oneway_stdout(void **st)
{
    (void)st;
    char cmd[600];
    snprintf(cmd, sizeof cmd, "%s --degree 3x4 --seed 3 --type1 --quiet", instrument);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    static rx r;
    memset(&r, 0, sizeof r);
    mem_out *sink = calloc(1, sizeof *sink);
    it2n_ostream os = mem_stream(sink);
    it2n_link_cfg cfg = {&os, NULL, on_rx, NULL, &r, 50, 10, 0, 0xDAE40002u, 0, 0, 0, 0, NULL};
    assert_int_equal(it2n_link_init(&r.l, &cfg), IT2N_OK);
    uint8_t buf[100];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0)
        it2n_link_input(&r.l, buf, n, 0);
    assert_int_equal(pclose(p), 0);
    assert_int_equal(r.committed, 1);
    assert_int_equal(r.solve_rc, IT2N_OK);
    expect_dataset(&r, 3, 4, IT2N_F_TYPE1, 3);
    free(sink);
}

int main(int argc, char **argv)
{
    if (argc > 1)
        instrument = argv[1];
    signal(SIGPIPE, SIG_IGN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lossy_pty),
        cmocka_unit_test(test_nack_is_reported),
        cmocka_unit_test(test_oneway_stdout),
    };
    return cmocka_run_group_tests_name("proto_instrument", tests, NULL, NULL);
}
