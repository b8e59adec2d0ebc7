/* loop — the daemon's single event loop (an epoll set): fd handlers, one-shot
 * timers on the monotonic clock, and post-iteration hooks (group commit).
 * Not thread-safe; callbacks may add and remove fds and timers freely. */
#ifndef IT2ND_LOOP_H
#define IT2ND_LOOP_H

#include <poll.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

typedef void (*loop_fd_cb)(void *arg, int fd, short revents);
typedef void (*loop_timer_cb)(void *arg);
typedef void (*loop_hook_cb)(void *arg);
/* A reader's chunk: n > 0 bytes at data (valid during the call only), 0 the
 * peer closed, < 0 -errno (a failed read, a hang-up, or a loop_send() that
 * could not send its whole buffer at once). */
typedef void (*loop_read_cb)(void *arg, int fd, const uint8_t *data, ssize_t n);

/* How the loop waits and moves stream data (`io` in [daemon]). */
enum loop_io { LOOP_IO_AUTO = 0, LOOP_IO_URING = 1, LOOP_IO_EPOLL = 2 };

/* Choose the I/O path before the first fd is added. LOOP_IO_AUTO: io_uring
 * when the kernel allows it (not disabled by sysctl or a seccomp filter),
 * else epoll; LOOP_IO_URING: io_uring or -1 (errno from the kernel);
 * LOOP_IO_EPOLL: epoll. Without a call the loop uses epoll. 0 or -1. */
int loop_init(enum loop_io io);
/* The path in use: "io_uring" or "epoll". */
const char *loop_io_name(void);

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
/* Stop watching fd (does not close it; a reader's read under way is
 * cancelled and its queued sends go out first). Safe inside a callback. */
void loop_del_fd(int fd);

/* Read a stream socket for cb: chunks of at most max_chunk bytes, each
 * handed to cb as it arrives. With io_uring the read rides on the wait's
 * system call (one io_uring_enter per wake-up carries every read and send:
 * the FC 23 benchmark, issue 22), and with max_chunk >= LOOP_RING_CHUNK on
 * 6.1+ it is one multishot read, not re-armed per chunk; with epoll it is a
 * recv() on readiness.
 * A hang-up or socket error comes to cb as 0 / -errno even while paused.
 * Removed with loop_del_fd(). 0 or -1. */
int loop_add_reader(int fd, size_t max_chunk, loop_read_cb cb, void *arg);
/* Stop (1) or resume (0) reading a reader (back-pressure): no chunk comes
 * while paused; what was read before the pause took hold (one single-shot
 * read, or the multishot read's chunks until its cancel) is kept and comes
 * after resume, in order. */
void loop_pause_reader(int fd, int paused);
/* Send len bytes on a reader's fd without blocking: whole or not at all
 * (epoll: send() now, -1 when short; io_uring: queued, sent in order at the
 * next wait, a short send reaches the reader's cb as -errno). The buffer
 * may be reused on return. 0 or -1. */
int loop_send(int fd, const void *buf, size_t len);

/* Chunks of a reader with max_chunk >= LOOP_RING_CHUNK come through one
 * multishot read (io_uring on 6.1+: armed once, not per request) and are
 * at most this size. */
#define LOOP_RING_CHUNK 256u

/* What the io_uring readers did (tests, diagnostics); zeros with epoll. */
struct loop_stats {
    unsigned long reads_armed;     /* recv requests put in the ring */
    unsigned long reads_multishot; /* of them multishot */
    unsigned long ring_dry;        /* multishot reads ended: no buffer left */
    unsigned buffers_out;          /* ring buffers the loop holds now */
};
void loop_get_stats(struct loop_stats *st);

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
