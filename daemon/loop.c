/* loop.c — see loop.h. Timers are a small table scanned linearly (tens of
 * them). Fds can be thousands (pending TCP connections, mb_tcp.c): an
 * index by fd number makes add/mod/del O(1). The wait is an epoll set,
 * not poll(): the kernel keeps the watched set between iterations, so a
 * wake-up costs what is ready, not every watched fd twice (the FC 23
 * benchmark, issue 22). Each entry carries a serial number in its epoll
 * data: an event queued for an fd deleted by an earlier callback (and
 * perhaps added again under the same number) is recognised and dropped.
 * An fd epoll refuses (EPERM: a regular file, always ready to poll()) is
 * kept on a side list and dispatched every iteration as poll() would. */
#include "loop.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <time.h>
#include <unistd.h>

struct fd_ent {
    int fd;
    short events;
    int always;   /* not in the epoll set: ready for what it waits for */
    uint32_t seq; /* serial, in the epoll data with the fd */
    loop_fd_cb cb;
    void *arg;
};

struct timer_ent {
    long id;
    uint64_t due; /* µs on CLOCK_MONOTONIC */
    loop_timer_cb cb;
    void *arg;
};

struct hook_ent {
    loop_hook_cb cb;
    void *arg;
};

static struct fd_ent *fds;
static size_t nfds, capfds;
static int epfd = -1;
static uint32_t next_seq;
static size_t nalways; /* entries with always set */
static size_t *fd_idx; /* fd number -> index in fds, SIZE_MAX none */
static size_t cap_idx;
static struct timer_ent *timers;
static size_t ntimers, captimers;
static struct hook_ent hooks[8];
static size_t nhooks;
static long next_timer_id = 1;
static int woken;
static uint64_t wake_us; /* loop_now_us() when the last wait returned, 0 before */
static int deleted;      /* entries marked by loop_del_fd, not yet compacted */

uint64_t loop_now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

uint64_t loop_now_ms(void)
{
    return loop_now_us() / 1000u;
}

uint64_t loop_wake_us(void)
{
    return wake_us ? wake_us : loop_now_us();
}

uint64_t loop_wake_ms(void)
{
    return loop_wake_us() / 1000u;
}

static size_t idx_of(int fd)
{
    return fd >= 0 && (size_t)fd < cap_idx ? fd_idx[fd] : SIZE_MAX;
}

int loop_add_fd(int fd, short events, loop_fd_cb cb, void *arg)
{
    if (fd < 0)
        return -1;
    if ((size_t)fd >= cap_idx) {
        size_t cap = cap_idx ? cap_idx : 64;
        while (cap <= (size_t)fd)
            cap *= 2;
        size_t *p = realloc(fd_idx, cap * sizeof *p);
        if (!p)
            return -1;
        for (size_t k = cap_idx; k < cap; k++)
            p[k] = SIZE_MAX;
        fd_idx = p;
        cap_idx = cap;
    }
    if (nfds == capfds) {
        size_t cap = capfds ? capfds * 2 : 16;
        struct fd_ent *p = realloc(fds, cap * sizeof *p);
        if (!p)
            return -1;
        fds = p;
        capfds = cap;
    }
    if (epfd < 0 && (epfd = epoll_create1(EPOLL_CLOEXEC)) < 0)
        return -1;
    uint32_t seq = ++next_seq;
    struct epoll_event ev = {.events = (uint32_t)(unsigned short)events,
                             .data.u64 = (uint64_t)seq << 32 | (uint32_t)fd};
    int always = 0;
    if (epoll_ctl(epfd, EPOLL_CTL_ADD, fd, &ev)) {
        /* Still registered: closed without loop_del_fd while a duplicate
         * keeps the file open. The new entry takes it over. */
        if (errno == EEXIST && !epoll_ctl(epfd, EPOLL_CTL_MOD, fd, &ev))
            ;
        else if (errno == EPERM)
            always = 1, nalways++;
        else
            return -1;
    }
    /* A deleted entry of the same fd may still be in the table (marked,
     * compacted at the end of the iteration): the index names the new one. */
    fds[nfds].fd = fd;
    fds[nfds].events = events;
    fds[nfds].always = always;
    fds[nfds].seq = seq;
    fds[nfds].cb = cb;
    fds[nfds].arg = arg;
    fd_idx[fd] = nfds;
    nfds++;
    return 0;
}

void loop_mod_fd(int fd, short events)
{
    size_t k = idx_of(fd);
    if (k == SIZE_MAX || fds[k].events == events)
        return;
    fds[k].events = events;
    if (!fds[k].always) {
        struct epoll_event ev = {.events = (uint32_t)(unsigned short)events,
                                 .data.u64 = (uint64_t)fds[k].seq << 32 | (uint32_t)fd};
        epoll_ctl(epfd, EPOLL_CTL_MOD, fd, &ev);
    }
}

void loop_del_fd(int fd)
{
    /* Mark only: the dispatcher may be iterating; compacted after. */
    size_t k = idx_of(fd);
    if (k != SIZE_MAX) {
        if (fds[k].always)
            nalways--;
        else
            epoll_ctl(epfd, EPOLL_CTL_DEL, fd, NULL); /* before the caller closes it */
        fds[k].fd = -1;
        fd_idx[fd] = SIZE_MAX;
        deleted = 1;
    }
}

long loop_add_timer(uint64_t delay_ms, loop_timer_cb cb, void *arg)
{
    return loop_add_timer_us(delay_ms * 1000u, cb, arg);
}

long loop_add_timer_us(uint64_t delay_us, loop_timer_cb cb, void *arg)
{
    if (ntimers == captimers) {
        size_t cap = captimers ? captimers * 2 : 16;
        struct timer_ent *p = realloc(timers, cap * sizeof *p);
        if (!p)
            return -1;
        timers = p;
        captimers = cap;
    }
    timers[ntimers].id = next_timer_id++;
    timers[ntimers].due = loop_now_us() + delay_us;
    timers[ntimers].cb = cb;
    timers[ntimers].arg = arg;
    return timers[ntimers++].id;
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
    if (nhooks == sizeof hooks / sizeof hooks[0])
        return -1;
    hooks[nhooks].cb = cb;
    hooks[nhooks].arg = arg;
    nhooks++;
    return 0;
}

void loop_wake(void)
{
    woken = 1;
}

static void compact_fds(void)
{
    size_t out = 0;
    if (!deleted) /* nothing marked: the common iteration */
        return;
    deleted = 0;
    for (size_t k = 0; k < nfds; k++)
        if (fds[k].fd >= 0) {
            fd_idx[fds[k].fd] = out;
            fds[out++] = fds[k];
        }
    nfds = out;
}

static void run_timers(void)
{
    uint64_t now = loop_now_us();
    /* Restart the scan after each callback: it may add or cancel timers. */
    for (;;) {
        size_t k;
        for (k = 0; k < ntimers; k++)
            if (timers[k].due <= now)
                break;
        if (k == ntimers)
            return;
        struct timer_ent t = timers[k];
        timers[k] = timers[--ntimers];
        t.cb(t.arg);
    }
}

int loop_run_once(int max_wait_ms)
{
    struct epoll_event evs[64];
    int rc = 0;
    /* µs: timers are kept to the microsecond (the RTU inter-frame silence
     * is 1.75 ms above 19200 Bd), so wait with epoll_pwait2 (a timespec),
     * not epoll_wait (ms). */
    int64_t timeout = max_wait_ms < 0 ? -1 : (int64_t)max_wait_ms * 1000;
    uint64_t now = loop_now_us();
    struct timespec ts;

    for (size_t k = 0; k < ntimers; k++) {
        int64_t d = (int64_t)(timers[k].due - now);
        int64_t dd = d < 0 ? 0 : d > 60000000 ? 60000000 : d;
        if (timeout < 0 || dd < timeout)
            timeout = dd;
    }
    if (woken || nalways) {
        timeout = 0;
        woken = 0;
    }
    ts.tv_sec = (time_t)(timeout / 1000000);
    ts.tv_nsec = (long)(timeout % 1000000) * 1000;
    if (epfd < 0 && (epfd = epoll_create1(EPOLL_CLOEXEC)) < 0)
        return -1;
    rc = epoll_pwait2(epfd, evs, (int)(sizeof evs / sizeof evs[0]), timeout < 0 ? NULL : &ts, NULL);
    if (rc < 0 && errno == ENOSYS) /* before Linux 5.11: ms, rounded up */
        rc = epoll_wait(epfd, evs, (int)(sizeof evs / sizeof evs[0]), timeout < 0 ? -1 : (int)((timeout + 999) / 1000));
    if (rc < 0 && errno != EINTR)
        return -1;
    wake_us = loop_now_us();
    /* An event whose entry was deleted by an earlier callback, or whose fd
     * number a new entry took since, is dropped (the serial differs). A
     * level-triggered fd not served this time is reported again. */
    for (int e = 0; e < rc; e++) {
        int fd = (int)(uint32_t)evs[e].data.u64;
        size_t k = idx_of(fd);
        if (k != SIZE_MAX && fds[k].seq == (uint32_t)(evs[e].data.u64 >> 32))
            fds[k].cb(fds[k].arg, fd, (short)evs[e].events);
    }
    /* Fds epoll cannot watch (regular files): always ready, as to poll(). */
    for (size_t k = 0, n = nfds; nalways && k < n; k++) {
        short rev = (short)(fds[k].events & (POLLIN | POLLOUT));
        if (fds[k].always && fds[k].fd >= 0 && rev)
            fds[k].cb(fds[k].arg, fds[k].fd, rev);
    }
    compact_fds();
    run_timers();
    for (size_t k = 0; k < nhooks; k++)
        hooks[k].cb(hooks[k].arg);
    compact_fds();
    return 0;
}

void loop_free(void)
{
    free(fds);
    free(fd_idx);
    free(timers);
    if (epfd >= 0)
        close(epfd);
    epfd = -1;
    nalways = 0;
    fds = NULL;
    fd_idx = NULL;
    timers = NULL;
    nfds = capfds = cap_idx = ntimers = captimers = nhooks = 0;
    wake_us = 0;
    deleted = 0;
}
