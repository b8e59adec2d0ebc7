/* fake_env.c — see fake_env.h. Replaces daemon/loop.c, daemon/log.c and the
 * counters of daemon/metrics.c. */
#include "fake_env.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "log.h"
#include "metrics.h"

#define FAKE_FDS 16
#define FAKE_TIMERS 32

struct fake_timer {
    long id;
    uint64_t due;
    loop_timer_cb cb;
    void *arg;
};

static struct fake_fd fds[FAKE_FDS];
static size_t nfds;
static int last_fd = -1;
static struct fake_timer timers[FAKE_TIMERS];
static size_t ntimers;
static long next_id = 1;
static uint64_t now_us = 1000000000; /* the fake clock, µs */
static unsigned log_errors;
static char log_last[1024];
static char note[1024];

void fuzz_note(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(note, sizeof note, fmt, ap);
    va_end(ap);
}

void fuzz_check(int ok, const char *what)
{
    if (!ok) {
        fprintf(stderr, "fuzz_daemon: invariant broken: %s\n", what);
        if (note[0])
            fprintf(stderr, "fuzz_daemon: context: %s\n", note);
        if (log_last[0])
            fprintf(stderr, "fuzz_daemon: last log: %s\n", log_last);
        abort();
    }
}

uint64_t loop_now_ms(void)
{
    return now_us / 1000u;
}

uint64_t loop_now_us(void)
{
    return now_us;
}

/* The fake clock only moves by hand, so the last wake is now. */
uint64_t loop_wake_ms(void)
{
    return now_us / 1000u;
}

uint64_t loop_wake_us(void)
{
    return now_us;
}

int loop_add_fd(int fd, short events, loop_fd_cb cb, void *arg)
{
    fuzz_check(fake_fd_find(fd) == NULL, "loop_add_fd: fd watched twice");
    if (nfds == FAKE_FDS)
        return -1;
    fds[nfds].fd = fd;
    fds[nfds].events = events;
    fds[nfds].cb = cb;
    fds[nfds].arg = arg;
    nfds++;
    last_fd = fd;
    return 0;
}

void loop_mod_fd(int fd, short events)
{
    for (size_t k = 0; k < nfds; k++)
        if (fds[k].fd == fd)
            fds[k].events = events;
}

/* Readers as loop.c's epoll path has them: the harness dispatches POLLIN,
 * the fake reads and hands the chunk over; pausing clears the events (the
 * harness sees a held reply as events == 0). */
struct fake_reader {
    int fd; /* -1: free */
    loop_read_cb cb;
    void *arg;
    size_t max;
    uint8_t buf[1024];
};
static struct fake_reader readers[FAKE_FDS];
static int readers_init;

static void fake_reader_event(void *arg, int fd, short revents)
{
    struct fake_reader *rd = arg;
    if (revents & POLLIN) {
        ssize_t r = recv(fd, rd->buf, rd->max, 0);
        if (r < 0 && (errno == EAGAIN || errno == EINTR))
            return;
        rd->cb(rd->arg, fd, rd->buf, r < 0 ? -errno : r);
    } else if (revents & (POLLHUP | POLLERR)) {
        rd->cb(rd->arg, fd, rd->buf, revents & POLLERR ? -EIO : 0);
    }
}

int loop_add_reader(int fd, size_t max_chunk, loop_read_cb cb, void *arg)
{
    if (!readers_init) {
        for (size_t k = 0; k < FAKE_FDS; k++)
            readers[k].fd = -1;
        readers_init = 1;
    }
    fuzz_check(max_chunk > 0 && max_chunk <= sizeof readers[0].buf, "loop_add_reader: chunk size");
    for (size_t k = 0; k < FAKE_FDS; k++)
        if (readers[k].fd < 0) {
            if (loop_add_fd(fd, POLLIN, fake_reader_event, &readers[k]))
                return -1;
            readers[k].fd = fd;
            readers[k].cb = cb;
            readers[k].arg = arg;
            readers[k].max = max_chunk;
            return 0;
        }
    return -1;
}

void loop_pause_reader(int fd, int paused)
{
    loop_mod_fd(fd, paused ? 0 : POLLIN);
}

int loop_send(int fd, const void *buf, size_t len)
{
    ssize_t w = send(fd, buf, len, MSG_NOSIGNAL | MSG_DONTWAIT);
    return w == (ssize_t)len ? 0 : -1;
}

void loop_del_fd(int fd)
{
    for (size_t k = 0; readers_init && k < FAKE_FDS; k++)
        if (readers[k].fd == fd)
            readers[k].fd = -1;
    for (size_t k = 0; k < nfds; k++)
        if (fds[k].fd == fd) {
            fds[k] = fds[--nfds];
            break;
        }
    if (last_fd == fd)
        last_fd = -1;
}

long loop_add_timer(uint64_t delay_ms, loop_timer_cb cb, void *arg)
{
    return loop_add_timer_us(delay_ms * 1000u, cb, arg);
}

long loop_add_timer_us(uint64_t delay_us, loop_timer_cb cb, void *arg)
{
    if (ntimers == FAKE_TIMERS)
        return -1;
    timers[ntimers].id = next_id;
    timers[ntimers].due = now_us + delay_us;
    timers[ntimers].cb = cb;
    timers[ntimers].arg = arg;
    ntimers++;
    return next_id++;
}

void loop_cancel_timer(long id)
{
    for (size_t k = 0; k < ntimers; k++)
        if (timers[k].id == id) {
            timers[k] = timers[--ntimers];
            return;
        }
}

int loop_add_hook(loop_hook_cb cb, void *arg)
{
    (void)cb;
    (void)arg;
    return 0;
}

void loop_wake(void)
{
}

int loop_run_once(int max_wait_ms)
{
    (void)max_wait_ms;
    return 0;
}

void loop_free(void)
{
    fake_reset();
}

const struct fake_fd *fake_fd_find(int fd)
{
    for (size_t k = 0; k < nfds; k++)
        if (fds[k].fd == fd)
            return &fds[k];
    return NULL;
}

const struct fake_fd *fake_fd_last(void)
{
    return last_fd >= 0 ? fake_fd_find(last_fd) : NULL;
}

int fake_fd_dispatch_as(int watched, int actual, short revents)
{
    const struct fake_fd *f = fake_fd_find(watched);
    if (f == NULL)
        return -1;
    struct fake_fd copy = *f; /* the handler may delete its own entry */
    copy.cb(copy.arg, actual, revents);
    return 0;
}

int fake_fd_dispatch(int fd, short revents)
{
    return fake_fd_dispatch_as(fd, fd, revents);
}

void fake_advance(uint64_t ms)
{
    fake_advance_us(ms * 1000u);
}

void fake_advance_us(uint64_t us)
{
    now_us += us;
    /* Timers re-arm themselves: run only those due now, each at most once
     * per call (a bounded loop even if a callback adds a 0 ms timer). */
    long limit = next_id;
    for (;;) {
        size_t k;
        for (k = 0; k < ntimers; k++)
            if (timers[k].due <= now_us && timers[k].id < limit)
                break;
        if (k == ntimers)
            return;
        struct fake_timer t = timers[k];
        timers[k] = timers[--ntimers];
        t.cb(t.arg);
    }
}

size_t fake_timers(void)
{
    return ntimers;
}

void fake_reset(void)
{
    nfds = 0;
    ntimers = 0;
    last_fd = -1;
}

/* ---- log.c ---- */

void log_open(int foreground, int verbosity)
{
    (void)foreground;
    (void)verbosity;
}

int log_level(void)
{
    return LOG_DEBUG;
}

void log_msg(int prio, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(log_last, sizeof log_last, fmt, ap);
    va_end(ap);
    if (prio <= LOG_ERR)
        log_errors++;
    if (getenv("IT2N_FUZZ_VERBOSE"))
        fprintf(stderr, "it2nd<%d>: %s\n", prio, log_last);
}

unsigned fake_log_errors(void)
{
    unsigned n = log_errors;
    log_errors = 0;
    return n;
}

const char *fake_log_last(void)
{
    return log_last;
}

/* metrics.c (libmicrohttpd) is not in the harnesses: its counters are
 * fed by mb_req.c and store.c, and dropped here. */
void metrics_modbus_reply(int fc, int exc)
{
    (void)fc;
    (void)exc;
}

void metrics_wal_fsync(uint64_t us, int ok)
{
    (void)us;
    (void)ok;
}
