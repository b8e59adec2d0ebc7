/* fake_env — stand-ins for daemon/loop.c and daemon/log.c so the daemon's
 * parsers run inside a fuzzer: a loop with a fake clock whose fd handlers
 * and timers the harness calls by hand (deterministic, no poll()), and a
 * log that formats every message (format bugs still trip ASan) but prints
 * only with IT2N_FUZZ_VERBOSE set. */
#ifndef FUZZ_DAEMON_FAKE_ENV_H
#define FUZZ_DAEMON_FAKE_ENV_H

#include <stddef.h>
#include <stdint.h>

#include "loop.h"

/* A watched fd as the daemon registered it. */
struct fake_fd {
    int fd;
    short events;
    loop_fd_cb cb;
    void *arg;
};

/* Entry of fd, or NULL when not watched. */
const struct fake_fd *fake_fd_find(int fd);
/* Most recently added watched fd, or NULL. */
const struct fake_fd *fake_fd_last(void);
/* Call the handler of fd as poll() would; 0, or -1 if fd is not watched. */
int fake_fd_dispatch(int fd, short revents);
/* Call a handler with another fd than the one registered (the handler
 * reads from its argument: lets the harness substitute a socket). */
int fake_fd_dispatch_as(int watched, int actual, short revents);

/* Advance the fake clock by ms and run the timers that fell due. */
void fake_advance(uint64_t ms);
/* The same in microseconds. */
void fake_advance_us(uint64_t us);
/* Pending timers. */
size_t fake_timers(void);

/* Drop every fd entry and timer (between independent runs). */
void fake_reset(void);

/* Number of log messages at LOG_ERR or worse since the last call. */
unsigned fake_log_errors(void);
/* Last message logged (any level). */
const char *fake_log_last(void);

/* Context printed when an invariant breaks (printf-style, kept short). */
void fuzz_note(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* Abort with a message when ok is false (the fuzzer's invariants). */
void fuzz_check(int ok, const char *what);

#endif
