/* test_loop.c — the poll loop with thousands of fds (pending TCP
 * connections, issue 20): every fd is polled (there used to be a fixed
 * 1024-entry poll array: a connection beyond it was never read), and an fd
 * closed and reused by a callback never gets the old entry's events.
 * Readers (issue 22: Modbus TCP data through io_uring): chunks in order,
 * pause and resume, a reset while paused, a client that does not read,
 * a reader dropped with a read and a send under way, a pause from inside
 * the callback with more data already read, a bulk stream. Every test runs
 * with io = epoll, with io = io_uring and small chunks (single-shot reads)
 * and with io = io_uring and chunks of LOOP_RING_CHUNK (one multishot read
 * through the loop's buffer ring); the io_uring groups are skipped, and
 * say so, when the kernel refuses io_uring. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "loop.h"

#define NPIPES 1500

static int pipes[NPIPES][2];
static int hits[NPIPES];

static void on_read(void *arg, int fd, short revents)
{
    char b[16];
    (void)revents;
    hits[(intptr_t)arg]++;
    (void)!read(fd, b, sizeof b);
}

/* Room for 2 x NPIPES descriptors, or skip (printed, not passed). */
static int raise_nofile(void)
{
    struct rlimit rl;
    if (getrlimit(RLIMIT_NOFILE, &rl))
        return -1;
    if (rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur < 2 * NPIPES + 64) {
        if (rl.rlim_max != RLIM_INFINITY && rl.rlim_max < 2 * NPIPES + 64)
            return -1;
        rl.rlim_cur = 2 * NPIPES + 64;
        if (setrlimit(RLIMIT_NOFILE, &rl))
            return -1;
    }
    return 0;
}

static void test_many_fds(void **st)
{
    (void)st;
    if (raise_nofile()) {
        print_message("skip: RLIMIT_NOFILE cannot hold %d descriptors\n", 2 * NPIPES);
        skip();
    }
    for (int k = 0; k < NPIPES; k++) {
        assert_int_equal(pipe2(pipes[k], O_NONBLOCK | O_CLOEXEC), 0);
        assert_int_equal(loop_add_fd(pipes[k][0], POLLIN, on_read, (void *)(intptr_t)k), 0);
    }
    /* The last ones, far beyond 1024 entries, and one at the start. */
    int probe[] = { 0, 1023, 1024, 1400, NPIPES - 1 };
    for (size_t k = 0; k < sizeof probe / sizeof probe[0]; k++)
        assert_int_equal(write(pipes[probe[k]][1], "x", 1), 1);
    assert_int_equal(loop_run_once(1000), 0);
    int total = 0;
    for (int k = 0; k < NPIPES; k++)
        total += hits[k];
    assert_int_equal(total, (int)(sizeof probe / sizeof probe[0]));
    for (size_t k = 0; k < sizeof probe / sizeof probe[0]; k++)
        assert_int_equal(hits[probe[k]], 1);
    for (int k = 0; k < NPIPES; k++) {
        loop_del_fd(pipes[k][0]);
        close(pipes[k][0]);
        close(pipes[k][1]);
    }
    loop_free();
}

/* A callback closes fd A and a new fd takes A's number (an accept right
 * after a close): the new fd's handler is not called with A's events. */
static int reuse_w = -1, reused_fd = -1, new_calls, old_calls;

static void on_new(void *arg, int fd, short revents)
{
    (void)arg;
    (void)fd;
    (void)revents;
    new_calls++;
}

static void on_old(void *arg, int fd, short revents)
{
    int p[2];
    (void)arg;
    (void)revents;
    old_calls++;
    loop_del_fd(fd);
    close(fd);
    close(reuse_w);
    /* The lowest free numbers: fd itself and reuse_w's. */
    assert_int_equal(pipe2(p, O_NONBLOCK | O_CLOEXEC), 0);
    reused_fd = p[0] == fd ? p[0] : -1; /* pipe2 takes the lowest free number first */
    assert_true(reused_fd >= 0);
    assert_int_equal(loop_add_fd(reused_fd, POLLIN, on_new, NULL), 0);
    reuse_w = p[1];
}

static void test_reused_fd(void **st)
{
    int p[2];
    (void)st;
    assert_int_equal(pipe2(p, O_NONBLOCK | O_CLOEXEC), 0);
    reuse_w = p[1];
    assert_int_equal(loop_add_fd(p[0], POLLIN, on_old, NULL), 0);
    assert_int_equal(write(p[1], "x", 1), 1);
    assert_int_equal(loop_run_once(1000), 0);
    assert_int_equal(old_calls, 1);
    assert_int_equal(new_calls, 0); /* the old entry's POLLIN did not reach it */
    /* The new fd is watched all the same: its own data reaches it. */
    assert_int_equal(write(reuse_w, "y", 1), 1);
    assert_int_equal(loop_run_once(1000), 0);
    assert_int_equal(new_calls, 1);
    loop_del_fd(reused_fd);
    close(reused_fd);
    close(reuse_w);
    loop_free();
}

/* loop_wake_us (issue 22: per-request stamps without a clock read) is the
 * time the last wait returned: in a callback it is after the wait started
 * (a 30 ms timer: at least 30 ms after) and never later than loop_now_us;
 * it stays the same within one iteration; before any wait it is fresh. */
static uint64_t cb_wake, cb_wake2, cb_now;

static void on_timer(void *arg)
{
    (void)arg;
    cb_wake = loop_wake_us();
    cb_now = loop_now_us();
    cb_wake2 = loop_wake_us();
}

static void test_wake_time(void **st)
{
    (void)st;
    uint64_t t0 = loop_now_us();
    assert_true(loop_wake_us() >= t0); /* before any wait: the clock */
    assert_true(loop_add_timer(30, on_timer, NULL) > 0);
    while (!cb_wake)
        assert_int_equal(loop_run_once(1000), 0);
    assert_true(cb_wake >= t0 + 30000u);
    assert_true(cb_wake <= cb_now);
    assert_true(cb_wake2 == cb_wake); /* one read per wake-up */
    assert_true(loop_wake_ms() == cb_wake / 1000u);
    loop_free();
}

/* ---- readers ---- */

static enum loop_io io_mode;
static int multishot; /* the group whose readers take ring-sized chunks */

/* A reader's max_chunk in this group. */
static size_t rsize(size_t n)
{
    return multishot && n < LOOP_RING_CHUNK ? LOOP_RING_CHUNK : n;
}

static int setup_io(void **st)
{
    (void)st;
    if (loop_init(io_mode)) {
        print_message("skip: the kernel refuses io_uring (%s)\n", strerror(errno));
        return -1;
    }
    assert_string_equal(loop_io_name(), io_mode == LOOP_IO_URING ? "io_uring" : "epoll");
    return 0;
}

/* A connected TCP pair on 127.0.0.1: *srv (non-blocking) and *cli. */
static int lfd = -1;

static void tcp_pair(int *srv, int *cli)
{
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    if (lfd < 0) {
        memset(&sa, 0, sizeof sa);
        sa.sin_family = AF_INET;
        sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        lfd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
        assert_true(lfd >= 0);
        assert_int_equal(bind(lfd, (struct sockaddr *)&sa, sizeof sa), 0);
        assert_int_equal(listen(lfd, 8), 0);
    }
    assert_int_equal(getsockname(lfd, (struct sockaddr *)&sa, &sl), 0);
    *cli = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    /* A read the loop should have answered fails the test, never hangs it. */
    struct timeval tv = {2, 0};
    assert_int_equal(setsockopt(*cli, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv), 0);
    assert_int_equal(connect(*cli, (struct sockaddr *)&sa, sizeof sa), 0);
    *srv = accept4(lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
    assert_true(*srv >= 0);
}

static char got[4096];
static size_t got_len;
static int got_end;  /* 1: end of stream, < 0: -errno */
static int got_calls;
static int drop_in_cb = -1;  /* fd to drop (and close) from inside the callback */
static int pause_in_cb = -1; /* fd to pause from inside the callback */

static void on_chunk(void *arg, int fd, const uint8_t *data, ssize_t n)
{
    (void)arg;
    got_calls++;
    if (n > 0) {
        assert_true(got_len + (size_t)n <= sizeof got);
        memcpy(got + got_len, data, (size_t)n);
        got_len += (size_t)n;
    } else {
        got_end = n == 0 ? 1 : (int)n;
    }
    if (fd == pause_in_cb) {
        loop_pause_reader(fd, 1);
        pause_in_cb = -1;
    }
    if (fd == drop_in_cb) {
        loop_del_fd(fd);
        close(fd);
        drop_in_cb = -1;
    }
}

static void reset_got(void)
{
    got_len = 0;
    got_end = 0;
    got_calls = 0;
}

/* Run the loop until want bytes (or an end) came, at most ~2 s. */
static void run_until(size_t want)
{
    for (int k = 0; k < 200 && got_len < want && !got_end; k++)
        assert_int_equal(loop_run_once(10), 0);
}

static void read_exact(int fd, char *buf, size_t n)
{
    size_t have = 0;
    while (have < n) {
        ssize_t r = recv(fd, buf + have, n - have, 0);
        assert_true(r > 0);
        have += (size_t)r;
    }
}

static void test_reader_chunks_and_sends(void **st)
{
    int srv, cli;
    char buf[64];
    (void)st;
    reset_got();
    tcp_pair(&srv, &cli);
    assert_int_equal(loop_add_reader(srv, rsize(8), on_chunk, NULL), 0);
    /* More than one chunk of 8: in order, nothing lost. */
    assert_int_equal(send(cli, "0123456789abcdefXYZ", 19, 0), 19);
    run_until(19);
    assert_int_equal(got_len, 19);
    assert_memory_equal(got, "0123456789abcdefXYZ", 19);
    /* Sends go out in order (io_uring: at the next wait). */
    assert_int_equal(loop_send(srv, "one,", 4), 0);
    assert_int_equal(loop_send(srv, "two", 3), 0);
    assert_int_equal(loop_run_once(0), 0);
    read_exact(cli, buf, 7);
    assert_memory_equal(buf, "one,two", 7);
    /* The peer closes: the end comes once. */
    close(cli);
    run_until(SIZE_MAX);
    assert_int_equal(got_end, 1);
    loop_del_fd(srv);
    close(srv);
    loop_free();
}

static void test_reader_pause(void **st)
{
    int srv, cli;
    (void)st;
    reset_got();
    tcp_pair(&srv, &cli);
    assert_int_equal(loop_add_reader(srv, rsize(64), on_chunk, NULL), 0);
    assert_int_equal(send(cli, "first", 5, 0), 5);
    run_until(5);
    assert_int_equal(got_len, 5);
    loop_pause_reader(srv, 1);
    assert_int_equal(send(cli, "second", 6, 0), 6);
    for (int k = 0; k < 5; k++)
        assert_int_equal(loop_run_once(10), 0);
    assert_int_equal(got_len, 5); /* nothing while paused */
    loop_pause_reader(srv, 0);
    assert_int_equal(send(cli, "third", 5, 0), 5);
    run_until(16);
    assert_int_equal(got_len, 16);
    assert_memory_equal(got, "firstsecondthird", 16);
    close(cli);
    loop_del_fd(srv);
    close(srv);
    loop_free();
}

/* A connection reset while its reader is paused is news at once (a
 * connection waiting for a slot must not hold it after its client left). */
static void test_reader_reset_while_paused(void **st)
{
    int srv, cli;
    struct linger lg = {1, 0};
    (void)st;
    reset_got();
    tcp_pair(&srv, &cli);
    assert_int_equal(loop_add_reader(srv, rsize(64), on_chunk, NULL), 0);
    assert_int_equal(loop_run_once(0), 0);
    loop_pause_reader(srv, 1);
    assert_int_equal(setsockopt(cli, SOL_SOCKET, SO_LINGER, &lg, sizeof lg), 0);
    close(cli); /* RST */
    run_until(SIZE_MAX);
    assert_true(got_end != 0);
    assert_int_equal(got_len, 0);
    loop_del_fd(srv);
    close(srv);
    loop_free();
}

/* A client that never reads: a send that the socket cannot take whole is
 * refused (epoll: loop_send -1; io_uring: the reader's callback gets
 * -errno), never queued without bound and never a blocked loop. */
static void test_reader_client_not_reading(void **st)
{
    int srv, cli, small = 4096, refused = 0;
    static char blob[200];
    (void)st;
    reset_got();
    tcp_pair(&srv, &cli);
    setsockopt(srv, SOL_SOCKET, SO_SNDBUF, &small, sizeof small);
    setsockopt(cli, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    assert_int_equal(loop_add_reader(srv, rsize(64), on_chunk, NULL), 0);
    for (int k = 0; k < 100000 && !refused && !got_end; k++) {
        if (loop_send(srv, blob, sizeof blob))
            refused = 1;
        if (k % 16 == 15)
            assert_int_equal(loop_run_once(0), 0);
    }
    assert_int_equal(loop_run_once(0), 0);
    assert_true(refused || got_end < 0);
    close(cli);
    loop_del_fd(srv);
    close(srv);
    loop_free();
}

/* A reader dropped (and its fd closed) with a read armed and a reply
 * queued: the reply still reaches its own client, which then sees the
 * end; the fd number taken by the next connection gets none of it. */
static void test_reader_drop_with_io_in_flight(void **st)
{
    int srv, cli, srv2, cli2;
    char buf[16];
    (void)st;
    reset_got();
    tcp_pair(&srv, &cli);
    assert_int_equal(loop_add_reader(srv, rsize(64), on_chunk, NULL), 0);
    assert_int_equal(loop_run_once(0), 0); /* the read is in the kernel now */
    assert_int_equal(loop_send(srv, "bye", 3), 0);
    loop_del_fd(srv);
    close(srv);
    tcp_pair(&srv2, &cli2); /* likely the same fd number */
    assert_int_equal(loop_add_reader(srv2, rsize(64), on_chunk, NULL), 0);
    for (int k = 0; k < 3; k++)
        assert_int_equal(loop_run_once(10), 0);
    read_exact(cli, buf, 3);
    assert_memory_equal(buf, "bye", 3);
    assert_int_equal(recv(cli, buf, sizeof buf, 0), 0); /* closed: the armed read let go */
    assert_int_equal(recv(cli2, buf, sizeof buf, MSG_DONTWAIT), -1);
    assert_int_equal(errno, EAGAIN);
    assert_int_equal(got_calls, 0);
    /* Dropped from inside its own callback. */
    drop_in_cb = srv2;
    assert_int_equal(send(cli2, "x", 1, 0), 1);
    run_until(1);
    assert_int_equal(got_len, 1);
    for (int k = 0; k < 3; k++)
        assert_int_equal(loop_run_once(10), 0);
    assert_int_equal(recv(cli2, buf, sizeof buf, 0), 0);
    close(cli);
    close(cli2);
    loop_free();
}

/* The reader pauses itself on its first chunk while more of the stream has
 * already been read (multishot: ring buffers completed in the same wait):
 * nothing more comes while paused, the rest comes in order after resume,
 * and every ring buffer goes back. Then the same with the reader dropped
 * while paused: its held buffers go back too. */
static void test_reader_pause_in_callback(void **st)
{
    int srv, cli;
    static char blob[600];
    struct loop_stats ls;
    (void)st;
    for (size_t k = 0; k < sizeof blob; k++)
        blob[k] = (char)('A' + k % 23);
    for (int drop = 0; drop < 2; drop++) {
        reset_got();
        tcp_pair(&srv, &cli);
        assert_int_equal(loop_add_reader(srv, rsize(64), on_chunk, NULL), 0);
        assert_int_equal(loop_run_once(0), 0); /* armed */
        pause_in_cb = srv;
        assert_int_equal(send(cli, blob, sizeof blob, 0), (ssize_t)sizeof blob);
        for (int k = 0; k < 200 && !got_calls; k++)
            assert_int_equal(loop_run_once(10), 0);
        for (int k = 0; k < 5; k++)
            assert_int_equal(loop_run_once(10), 0);
        assert_int_equal(got_calls, 1); /* only the first chunk while paused */
        assert_true(got_len > 0 && got_len <= rsize(64));
        if (drop) {
            loop_del_fd(srv);
            close(srv);
            for (int k = 0; k < 3; k++)
                assert_int_equal(loop_run_once(10), 0);
        } else {
            loop_pause_reader(srv, 0);
            run_until(sizeof blob);
            assert_int_equal(got_len, sizeof blob);
            assert_memory_equal(got, blob, sizeof blob);
            loop_del_fd(srv);
            close(srv);
        }
        loop_get_stats(&ls);
        assert_int_equal(ls.buffers_out, 0);
        if (multishot && loop_io_name()[0] == 'i')
            assert_true(ls.reads_multishot >= 1);
        close(cli);
    }
    loop_free();
}

/* A stream far larger than the buffer ring (256 KB, the client writing as
 * the socket takes it): every byte in order. With multishot reads a read is
 * armed once for many chunks (again only when the ring ran dry). */
static size_t bulk_at;
static int bulk_bad, bulk_chunks;

static void on_bulk(void *arg, int fd, const uint8_t *data, ssize_t n)
{
    (void)arg;
    (void)fd;
    bulk_chunks++;
    for (ssize_t k = 0; k < n; k++, bulk_at++)
        bulk_bad += data[k] != (uint8_t)(bulk_at % 251u);
    if (n <= 0)
        bulk_bad++;
}

static void test_reader_bulk(void **st)
{
    enum { TOTAL = 256 * 1024 };
    static uint8_t blob[TOTAL];
    int srv, cli;
    size_t sent = 0;
    struct loop_stats ls;
    (void)st;
    for (size_t k = 0; k < TOTAL; k++)
        blob[k] = (uint8_t)(k % 251u);
    bulk_at = 0;
    bulk_bad = bulk_chunks = 0;
    tcp_pair(&srv, &cli);
    assert_int_equal(fcntl(cli, F_SETFL, O_NONBLOCK), 0);
    assert_int_equal(loop_add_reader(srv, rsize(64), on_bulk, NULL), 0);
    for (int k = 0; k < 100000 && bulk_at < TOTAL && !bulk_bad; k++) {
        if (sent < TOTAL) {
            ssize_t w = send(cli, blob + sent, TOTAL - sent, 0);
            if (w > 0)
                sent += (size_t)w;
        }
        assert_int_equal(loop_run_once(sent < TOTAL ? 0 : 10), 0);
    }
    assert_int_equal(bulk_bad, 0);
    assert_int_equal(bulk_at, TOTAL);
    loop_get_stats(&ls);
    print_message("bulk: %d chunks, %lu reads armed (%lu multishot, %lu ended by a dry ring), %u buffers out\n",
                  bulk_chunks, ls.reads_armed, ls.reads_multishot, ls.ring_dry, ls.buffers_out);
    if (multishot && loop_io_name()[0] == 'i') {
        assert_true(ls.reads_multishot >= 1);
        assert_true(ls.reads_armed < (unsigned long)bulk_chunks / 4);
    }
    loop_del_fd(srv);
    close(srv);
    close(cli);
    loop_get_stats(&ls);
    assert_int_equal(ls.buffers_out, 0);
    loop_free();
}

/* The buffer ring runs dry: NA readers pause on their first chunk with
 * a burst already read ahead (held: Linux reads up to 32 chunks per
 * wake-up, so NA x 31 > the ring's 256), then reader B's data comes. Every
 * reader gets every byte in order (B, more than the buffers left, while
 * the others are paused: its multishot read runs dry and it goes on
 * single-shot), and every
 * buffer goes back to the ring. */
#define NA 12
static size_t na_at[NA];
static int na_fd[NA], na_bad, na_calls[NA];
static char got_b[4096];
static size_t got_b_len;

static void on_chunk_na(void *arg, int fd, const uint8_t *data, ssize_t n)
{
    int i = (int)(intptr_t)arg;
    if (n <= 0) {
        na_bad++;
        return;
    }
    for (ssize_t k = 0; k < n; k++, na_at[i]++)
        na_bad += data[k] != (uint8_t)((na_at[i] + (size_t)i) % 251u);
    if (!na_calls[i]++)
        loop_pause_reader(fd, 1);
}

static void on_chunk_b(void *arg, int fd, const uint8_t *data, ssize_t n)
{
    (void)arg;
    (void)fd;
    if (n > 0 && got_b_len + (size_t)n <= sizeof got_b) {
        memcpy(got_b + got_b_len, data, (size_t)n);
        got_b_len += (size_t)n;
    }
}

static void test_reader_ring_dry(void **st)
{
    enum { BURST = 16 * 1024 };
    static uint8_t blob[BURST + 251];
    static char blob_b[3000]; /* more than the buffers left */
    int ca[NA], b, cb;
    struct loop_stats ls;
    size_t total = 0;
    (void)st;
    if (!multishot || loop_io_name()[0] != 'i') {
        print_message("skip: the buffer ring is the multishot group's\n");
        skip();
    }
    for (size_t k = 0; k < sizeof blob; k++)
        blob[k] = (uint8_t)(k % 251u);
    for (size_t k = 0; k < sizeof blob_b; k++)
        blob_b[k] = (char)('a' + k % 26);
    na_bad = 0;
    got_b_len = 0;
    for (int i = 0; i < NA; i++) {
        na_at[i] = 0;
        na_calls[i] = 0;
        tcp_pair(&na_fd[i], &ca[i]);
        assert_int_equal(loop_add_reader(na_fd[i], rsize(64), on_chunk_na, (void *)(intptr_t)i), 0);
    }
    tcp_pair(&b, &cb);
    assert_int_equal(loop_add_reader(b, rsize(64), on_chunk_b, NULL), 0);
    assert_int_equal(loop_run_once(0), 0); /* all armed */
    for (int i = 0; i < NA; i++) /* reader i's stream starts at blob[i] */
        assert_int_equal(send(ca[i], blob + i, BURST, 0), BURST);
    for (int k = 0; k < 5; k++)
        assert_int_equal(loop_run_once(10), 0);
    loop_get_stats(&ls);
    print_message("ring dry: %d paused readers hold %u buffers, %lu reads ended by a dry ring\n", NA,
                  ls.buffers_out, ls.ring_dry);
    for (int i = 0; i < NA; i++)
        assert_int_equal(na_calls[i], 1); /* paused after the first chunk */
    assert_true(ls.ring_dry >= 1);
    unsigned long single = ls.reads_armed - ls.reads_multishot;
    assert_int_equal(send(cb, blob_b, sizeof blob_b, 0), (ssize_t)sizeof blob_b);
    for (int k = 0; k < 200 && got_b_len < sizeof blob_b; k++)
        assert_int_equal(loop_run_once(10), 0);
    assert_int_equal(got_b_len, sizeof blob_b);
    assert_memory_equal(got_b, blob_b, sizeof blob_b);
    loop_get_stats(&ls);
    assert_true(ls.reads_armed - ls.reads_multishot > single); /* B went on single-shot */
    for (int i = 0; i < NA; i++) {
        assert_int_equal(na_calls[i], 1);
        loop_pause_reader(na_fd[i], 0);
    }
    for (int k = 0; k < 1000 && total < (size_t)NA * BURST && !na_bad; k++) {
        assert_int_equal(loop_run_once(10), 0);
        total = 0;
        for (int i = 0; i < NA; i++)
            total += na_at[i];
    }
    assert_int_equal(na_bad, 0);
    assert_int_equal(total, (size_t)NA * BURST);
    loop_get_stats(&ls);
    assert_int_equal(ls.buffers_out, 0);
    for (int i = 0; i < NA; i++) {
        loop_del_fd(na_fd[i]);
        close(na_fd[i]);
        close(ca[i]);
    }
    loop_del_fd(b);
    close(b);
    close(cb);
    loop_free();
}

/* Each test from a clean slate: the group runs three times. */
static int setup_plain(void **st)
{
    memset(hits, 0, sizeof hits);
    old_calls = new_calls = 0;
    cb_wake = cb_wake2 = cb_now = 0;
    loop_free();
    return setup_io(st);
}

#define BOTH(t) cmocka_unit_test_setup(t, setup_plain)

int main(void)
{
    const struct CMUnitTest tests[] = {
        BOTH(test_many_fds),
        BOTH(test_reused_fd),
        BOTH(test_wake_time),
        BOTH(test_reader_chunks_and_sends),
        BOTH(test_reader_pause),
        BOTH(test_reader_reset_while_paused),
        BOTH(test_reader_client_not_reading),
        BOTH(test_reader_drop_with_io_in_flight),
        BOTH(test_reader_pause_in_callback),
        BOTH(test_reader_bulk),
        BOTH(test_reader_ring_dry),
    };
    int rc;
    io_mode = LOOP_IO_EPOLL;
    rc = cmocka_run_group_tests_name("loop, io = epoll", tests, NULL, NULL);
    io_mode = LOOP_IO_URING;
    if (loop_init(LOOP_IO_URING)) {
        print_message("skip: io = io_uring: the kernel refuses io_uring (%s); its tests not run\n", strerror(errno));
        return rc;
    }
    loop_free();
    rc |= cmocka_run_group_tests_name("loop, io = io_uring, single-shot reads", tests, NULL, NULL);
    multishot = 1;
    rc |= cmocka_run_group_tests_name("loop, io = io_uring, multishot reads", tests, NULL, NULL);
    return rc;
}
