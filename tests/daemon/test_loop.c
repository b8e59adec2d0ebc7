/* test_loop.c — the poll loop with thousands of fds (pending TCP
 * connections, issue 20): every fd is polled (there used to be a fixed
 * 1024-entry poll array: a connection beyond it was never read), and an fd
 * closed and reused by a callback never gets the old entry's events. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <fcntl.h>
#include <sys/resource.h>
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_many_fds),
        cmocka_unit_test(test_reused_fd),
        cmocka_unit_test(test_wake_time),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
