/* loop — the daemon's single event loop (an epoll set): fd handlers, one-shot
 * timers on the monotonic clock, and post-iteration hooks (group commit).
 * Not thread-safe; callbacks may add and remove fds and timers freely. */
#ifndef IT2ND_LOOP_H
#define IT2ND_LOOP_H

#include <poll.h>
#include <stdint.h>

typedef void (*loop_fd_cb)(void *arg, int fd, short revents);
typedef void (*loop_timer_cb)(void *arg);
typedef void (*loop_hook_cb)(void *arg);

/* Milliseconds / microseconds on CLOCK_MONOTONIC. */
uint64_t loop_now_ms(void);
uint64_t loop_now_us(void);
/* The same, read once when the current wait returned (fresh before the
 * first): per-request time stamps (idle and byte timeouts, eviction
 * order) without a clock read per request. Never later than loop_now_*. */
uint64_t loop_wake_ms(void);
uint64_t loop_wake_us(void);

/* Watch fd for `events` (POLLIN/POLLOUT). One handler per fd; 0 or -1. */
int loop_add_fd(int fd, short events, loop_fd_cb cb, void *arg);
/* Change the events of a watched fd. */
void loop_mod_fd(int fd, short events);
/* Stop watching fd (does not close it). Safe inside a callback. */
void loop_del_fd(int fd);

/* Call cb(arg) once, delay_ms from now. Returns a timer id (> 0) or -1. */
long loop_add_timer(uint64_t delay_ms, loop_timer_cb cb, void *arg);
/* The same with a delay in microseconds (timers are kept to the µs). */
long loop_add_timer_us(uint64_t delay_us, loop_timer_cb cb, void *arg);
/* Cancel a pending timer; unknown ids are ignored. */
void loop_cancel_timer(long id);

/* Hook called after every iteration's callbacks (e.g. fsync then reply). */
int loop_add_hook(loop_hook_cb cb, void *arg);

/* Ask the next iteration not to sleep (work queued by a hook). */
void loop_wake(void);

/* Run one iteration: wait for at most max_wait_ms (-1 = until the next
 * timer), dispatch fds, timers, hooks. Returns 0, or -1 on poll failure
 * other than EINTR. */
int loop_run_once(int max_wait_ms);

/* Release everything (fds are not closed). */
void loop_free(void);

#endif
