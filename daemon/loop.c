/* loop.c — see loop.h. Timers are a small table scanned linearly (tens of
 * them). Fds can be thousands (pending TCP connections, mb_tcp.c): an
 * index by fd number makes add/mod/del O(1). The wait is an epoll set,
 * not poll(): the kernel keeps the watched set between iterations, so a
 * wake-up costs what is ready, not every watched fd twice (the FC 23
 * benchmark, issue 22). Each entry carries a serial number in its epoll
 * data: an event queued for an fd deleted by an earlier callback (and
 * perhaps added again under the same number) is recognised and dropped.
 * An fd epoll refuses (EPERM: a regular file, always ready to poll()) is
 * kept on a side list and dispatched every iteration as poll() would.
 *
 * With io_uring (loop_init) the wait is io_uring_enter: the epoll set is
 * one poll request in the ring (its readiness wakes the wait, then
 * epoll_wait(0) says which fds), and readers (Modbus TCP connections) read
 * and send through the ring, so a wake-up that answers requests costs one
 * system call where epoll costs a wait, a recv and a send each. A reader's
 * fd also stays in the epoll set with no events: a hang-up or error while
 * it is paused still comes through. A reader with chunks of at least
 * LOOP_RING_CHUNK reads through one multishot recv into a shared buffer
 * ring (kept armed across requests; cancelled on pause, what it read
 * meanwhile held in order; single-shot when the ring runs dry). Sends
 * carry MSG_DONTWAIT: each is tried
 * in the submitting call and never waits in the kernel, so the staging
 * buffer is free again once io_uring_submit returns, and a client too slow
 * to take a reply gets the same "short send" as with send(). */
#include "loop.h"

#include <errno.h>
#include <liburing.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

/* A reader: its buffer and what is in flight in the ring. Owned by the
 * loop, freed once deleted with nothing in flight (the kernel may still
 * write the buffer of a cancelled read until its completion is reaped). */
struct reader {
    int fd;
    int dead;                 /* loop_del_fd done */
    int paused;               /* loop_pause_reader */
    int armed;                /* a recv in the ring */
    int multi;                /* ... a multishot one (chunks in the loop's buffer ring) */
    int stashed;              /* a chunk read while paused, stash_n bytes in buf */
    int held_head, held_tail; /* ring buffers read while paused, in order; -1 none */
    int end_held;             /* the end (end_res: 0 or -errno) came after them */
    int end_res;
    int single_next; /* the ring ran dry: the next read is single-shot */
    int on_due;      /* in the due list (stash or held chunks to hand over) */
    ssize_t stash_n;
    unsigned inflight;     /* completions to come: recv + sends */
    unsigned sends;        /* sends in flight */
    size_t sent_want;      /* bytes of the sends in flight */
    size_t sent_done;      /* bytes they sent so far */
    int send_err;          /* first failure among them (-errno) */
    struct reader *due;    /* next in the due list */
    struct reader *all_nx; /* every reader, for loop_free */
    struct reader *all_pv;
    loop_read_cb cb;
    void *arg;
    size_t max;
    uint8_t buf[];
};

struct fd_ent {
    int fd;
    short events;
    int always;   /* not in the epoll set: ready for what it waits for */
    uint32_t seq; /* serial, in the epoll data with the fd */
    loop_fd_cb cb;
    void *arg;
    struct reader *rd; /* a reader's entry, NULL for a plain fd */
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

/* io_uring (use_ring): user_data is a reader's address with a tag in its
 * low bits (malloc aligns to 8 at least), or a tag alone. */
#define TAG_EPOLL 1u
#define TAG_RECV 2u
#define TAG_SEND 3u
#define TAG_CANCEL 4u
#define TAG_MASK 7u
#define RING_ENTRIES 1024u
#define STAGE_CAP 65536u
static struct io_uring ring;
static int use_ring;
static int epoll_armed; /* the ring's poll of epfd is in flight */
static int poll_first;  /* a recv waits for readiness before trying (6.1+) */
static uint8_t *stage;  /* sends' bytes until io_uring_submit */
static size_t stage_len;
static unsigned sends_queued;   /* sends in the SQ, not yet submitted */
static struct reader *due_head; /* stashes handed over at the next iteration */
/* Multishot reads (6.0, with DEFER_TASKRUN's 6.1): one recv stays armed
 * across requests and takes a buffer of this ring for each chunk, so a
 * request costs no re-arm. A chunk read while its reader is paused keeps
 * its buffer (held, in a per-reader list) until handed over. */
#define RB_ENTRIES 256u
#define RB_SIZE LOOP_RING_CHUNK
#define RB_GROUP 1
static struct io_uring_buf_ring *rb_ring;
static uint8_t *rb_bufs;
static int rb_next[RB_ENTRIES];     /* held list links */
static unsigned rb_len[RB_ENTRIES]; /* bytes in a held buffer */
static unsigned rb_out;             /* buffers not in the ring (held) */
static struct loop_stats stats;
static struct reader *all_readers;

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
    fds[nfds].rd = NULL;
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

static void reader_drop(struct reader *rd);

void loop_del_fd(int fd)
{
    /* Mark only: the dispatcher may be iterating; compacted after. */
    size_t k = idx_of(fd);
    if (k != SIZE_MAX) {
        if (fds[k].always)
            nalways--;
        else
            epoll_ctl(epfd, EPOLL_CTL_DEL, fd, NULL); /* before the caller closes it */
        if (fds[k].rd)
            reader_drop(fds[k].rd);
        fds[k].fd = -1;
        fds[k].rd = NULL;
        fd_idx[fd] = SIZE_MAX;
        deleted = 1;
    }
}

/* ---- io_uring and readers ---- */

static void rb_setup(void);

int loop_init(enum loop_io io)
{
    struct io_uring_params p;
    int rc;
    if (use_ring || io == LOOP_IO_EPOLL)
        return 0;
    stage = malloc(STAGE_CAP);
    if (!stage)
        return -1;
    /* Completions run only when the loop waits (DEFER_TASKRUN, 6.1), else
     * at the next system call (COOP_TASKRUN, 5.19), else by interrupt. */
    static const unsigned flags[] = {IORING_SETUP_SINGLE_ISSUER | IORING_SETUP_DEFER_TASKRUN, IORING_SETUP_COOP_TASKRUN,
                                     0};
    rc = -ENOSYS;
    for (size_t k = 0; k < sizeof flags / sizeof flags[0]; k++) {
        memset(&p, 0, sizeof p);
        p.flags = flags[k];
        rc = io_uring_queue_init_params(RING_ENTRIES, &ring, &p);
        if (rc != -EINVAL)
            break;
    }
    /* Submitting and waiting with a timeout in one call needs EXT_ARG (5.11). */
    if (rc == 0 && !(p.features & IORING_FEAT_EXT_ARG)) {
        io_uring_queue_exit(&ring);
        rc = -ENOSYS;
    }
    if (rc < 0) {
        free(stage);
        stage = NULL;
        errno = -rc;
        return io == LOOP_IO_URING ? -1 : 0;
    }
    /* The ring's own fd registered (5.18): no fd lookup per io_uring_enter;
     * refused by an older kernel, which only costs that lookup. */
    (void)io_uring_register_ring_fd(&ring);
    /* A kernel that took DEFER_TASKRUN (6.1) knows IORING_RECVSEND_POLL_FIRST
     * (5.19): a read is armed right after a reply, before the client can
     * have sent its next request, so it waits for readiness untried. */
    poll_first = (p.flags & IORING_SETUP_DEFER_TASKRUN) != 0;
    use_ring = 1;
    if (poll_first)
        rb_setup();
    return 0;
}

static uint8_t *rb_buf(int bid)
{
    return rb_bufs + (size_t)bid * RB_SIZE;
}

/* The buffer ring of multishot reads; without it (refused, no memory)
 * every read is single-shot. */
static void rb_setup(void)
{
    struct io_uring_buf_reg reg;
    void *mem = NULL;
    if (posix_memalign(&mem, 4096, RB_ENTRIES * sizeof(struct io_uring_buf)))
        return;
    rb_bufs = malloc((size_t)RB_ENTRIES * RB_SIZE);
    memset(&reg, 0, sizeof reg);
    reg.ring_addr = (uint64_t)(uintptr_t)mem;
    reg.ring_entries = RB_ENTRIES;
    reg.bgid = RB_GROUP;
    if (!rb_bufs || io_uring_register_buf_ring(&ring, &reg, 0)) {
        free(mem);
        free(rb_bufs);
        rb_bufs = NULL;
        return;
    }
    rb_ring = mem;
    io_uring_buf_ring_init(rb_ring);
    for (unsigned b = 0; b < RB_ENTRIES; b++)
        io_uring_buf_ring_add(rb_ring, rb_buf((int)b), RB_SIZE, (unsigned short)b, io_uring_buf_ring_mask(RB_ENTRIES),
                              (int)b);
    io_uring_buf_ring_advance(rb_ring, (int)RB_ENTRIES);
    rb_out = 0;
}

/* A buffer back into the ring. */
static void rb_recycle(int bid)
{
    io_uring_buf_ring_add(rb_ring, rb_buf(bid), RB_SIZE, (unsigned short)bid, io_uring_buf_ring_mask(RB_ENTRIES), 0);
    io_uring_buf_ring_advance(rb_ring, 1);
    rb_out--;
}

void loop_get_stats(struct loop_stats *st)
{
    *st = stats;
    st->buffers_out = rb_out;
}

const char *loop_io_name(void)
{
    return use_ring ? "io_uring" : "epoll";
}

/* The staged bytes are free once nothing waits in the SQ (every send
 * was tried in the submitting call). */
static void stage_release(void)
{
    if (!io_uring_sq_ready(&ring))
        stage_len = 0, sends_queued = 0;
}

/* Submit what is queued. */
static void ring_flush(void)
{
    if (io_uring_sq_ready(&ring))
        io_uring_submit(&ring);
    stage_release();
}

static struct io_uring_sqe *ring_sqe(void)
{
    struct io_uring_sqe *sqe = io_uring_get_sqe(&ring);
    if (!sqe) {
        ring_flush();
        sqe = io_uring_get_sqe(&ring);
    }
    return sqe;
}

static void reader_free(struct reader *rd)
{
    if (!rd->dead || rd->inflight || rd->on_due)
        return;
    *(rd->all_pv ? &rd->all_pv->all_nx : &all_readers) = rd->all_nx;
    if (rd->all_nx)
        rd->all_nx->all_pv = rd->all_pv;
    free(rd);
}

static void reader_arm(struct reader *rd)
{
    struct io_uring_sqe *sqe;
    if (rd->dead || rd->paused || rd->armed || rd->stashed || rd->held_head >= 0 || rd->end_held || !(sqe = ring_sqe()))
        return;
    /* Multishot while the ring has buffers to spare (paused readers hold
     * some), chunks of RB_SIZE; else single-shot into the reader's buffer. */
    rd->multi = rb_ring && rd->max >= RB_SIZE && !rd->single_next && rb_out < RB_ENTRIES / 2;
    rd->single_next = 0;
    stats.reads_armed++;
    stats.reads_multishot += (unsigned)rd->multi;
    if (rd->multi) {
        io_uring_prep_recv_multishot(sqe, rd->fd, NULL, 0, 0);
        sqe->flags |= IOSQE_BUFFER_SELECT;
        sqe->buf_group = RB_GROUP;
    } else {
        io_uring_prep_recv(sqe, rd->fd, rd->buf, rd->max, 0);
    }
    if (poll_first)
        sqe->ioprio |= IORING_RECVSEND_POLL_FIRST;
    io_uring_sqe_set_data64(sqe, (uint64_t)(uintptr_t)rd | TAG_RECV);
    rd->armed = 1;
    rd->inflight++;
}

/* Hand a chunk (or the end, or an error) to the reader's owner; read on
 * after data unless it paused or dropped the reader meanwhile. */
static void reader_deliver_from(struct reader *rd, const uint8_t *data, ssize_t n)
{
    rd->inflight++; /* the callback may drop the reader: freed after it */
    rd->cb(rd->arg, rd->fd, data, n);
    rd->inflight--;
    if (rd->dead)
        reader_free(rd);
    else if (use_ring && n > 0)
        reader_arm(rd);
}

static void reader_deliver(struct reader *rd, ssize_t n)
{
    reader_deliver_from(rd, rd->buf, n);
}

/* Held ring buffers (and the end after them) handed over in order while
 * the reader is not paused, each buffer back into the ring after; then
 * reading goes on. */
static void reader_drain_held(struct reader *rd)
{
    rd->inflight++;
    while (!rd->dead && !rd->paused && rd->held_head >= 0) {
        int bid = rd->held_head;
        rd->held_head = rb_next[bid];
        if (rd->held_head < 0)
            rd->held_tail = -1;
        /* Out of the list before the call (which may pause or drop). */
        reader_deliver_from(rd, rb_buf(bid), (ssize_t)rb_len[bid]);
        rb_recycle(bid);
    }
    if (!rd->dead && !rd->paused && rd->end_held) {
        rd->end_held = 0;
        reader_deliver_from(rd, rd->buf, rd->end_res);
    }
    rd->inflight--;
    if (rd->dead)
        reader_free(rd);
    else
        reader_arm(rd);
}

static void reader_hold(struct reader *rd, int bid, unsigned len)
{
    rb_next[bid] = -1;
    rb_len[bid] = len;
    if (rd->held_tail >= 0)
        rb_next[rd->held_tail] = bid;
    else
        rd->held_head = bid;
    rd->held_tail = bid;
}

/* Into the due list: its stash or held chunks handed over at the end of
 * the current wait's dispatch. */
static void reader_due(struct reader *rd)
{
    rd->on_due = 1;
    rd->due = due_head;
    due_head = rd;
}

static void reader_cancel(struct reader *rd)
{
    struct io_uring_sqe *sqe = ring_sqe();
    if (sqe) {
        io_uring_prep_cancel64(sqe, (uint64_t)(uintptr_t)rd | TAG_RECV, 0);
        io_uring_sqe_set_data64(sqe, TAG_CANCEL);
    }
}

static void reader_drop(struct reader *rd)
{
    rd->dead = 1;
    /* Held buffers: ours since their completions, the kernel writes them no
     * more. */
    while (use_ring && rd->held_head >= 0) {
        int bid = rd->held_head;
        rd->held_head = rb_next[bid];
        rb_recycle(bid);
    }
    rd->held_tail = -1;
    if (!use_ring) {
        reader_free(rd);
        return;
    }
    if (rd->armed)
        reader_cancel(rd);
    /* Queued sends and re-arms name this fd number: out before the caller
     * closes it (and a new connection may take the number). */
    ring_flush();
    reader_free(rd);
}

/* The reader's entry in the epoll set: with epoll its data, with io_uring
 * only a hang-up or error (no events asked). */
static void reader_event(void *arg, int fd, short revents)
{
    struct reader *rd = arg;
    if ((revents & POLLIN) && !use_ring && !rd->paused) {
        ssize_t r = recv(fd, rd->buf, rd->max, 0);
        if (r < 0 && (errno == EAGAIN || errno == EINTR))
            return;
        reader_deliver(rd, r < 0 ? -errno : r);
        return;
    }
    if (revents & POLLERR) {
        int err = 0;
        socklen_t l = sizeof err;
        if (getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &l) || !err)
            err = EIO;
        reader_deliver(rd, -err);
    } else if (revents & (POLLHUP | POLLNVAL)) {
        reader_deliver(rd, 0);
    }
}

int loop_add_reader(int fd, size_t max_chunk, loop_read_cb cb, void *arg)
{
    struct reader *rd;
    if (!max_chunk || !(rd = calloc(1, sizeof *rd + max_chunk)))
        return -1;
    rd->fd = fd;
    rd->cb = cb;
    rd->arg = arg;
    rd->max = max_chunk;
    rd->held_head = rd->held_tail = -1;
    if (loop_add_fd(fd, use_ring ? 0 : POLLIN, reader_event, rd)) {
        free(rd);
        return -1;
    }
    fds[fd_idx[fd]].rd = rd;
    rd->all_nx = all_readers;
    if (all_readers)
        all_readers->all_pv = rd;
    all_readers = rd;
    if (use_ring)
        reader_arm(rd);
    return 0;
}

static struct reader *reader_of(int fd)
{
    size_t k = idx_of(fd);
    return k == SIZE_MAX ? NULL : fds[k].rd;
}

void loop_pause_reader(int fd, int paused)
{
    struct reader *rd = reader_of(fd);
    if (!rd || rd->paused == !!paused)
        return;
    rd->paused = !!paused;
    if (!use_ring) {
        loop_mod_fd(fd, paused ? 0 : POLLIN);
        return;
    }
    if (paused) {
        /* A single-shot read under way is kept (stashed) when it completes;
         * a multishot one is cancelled, what it reads until then held. */
        if (rd->armed && rd->multi)
            reader_cancel(rd);
        return;
    }
    if ((rd->stashed || rd->held_head >= 0 || rd->end_held) && !rd->on_due) {
        /* Handed over by the loop, not from inside the caller's code. */
        reader_due(rd);
        loop_wake();
    } else {
        reader_arm(rd);
    }
}

int loop_send(int fd, const void *buf, size_t len)
{
    struct reader *rd = reader_of(fd);
    struct io_uring_sqe *sqe;
    if (!use_ring || !rd) {
        ssize_t w = send(fd, buf, len, MSG_NOSIGNAL | MSG_DONTWAIT);
        return w == (ssize_t)len ? 0 : -1;
    }
    if (len > STAGE_CAP - stage_len || !io_uring_sq_space_left(&ring))
        ring_flush();
    if (len > STAGE_CAP - stage_len || !(sqe = io_uring_get_sqe(&ring)))
        return -1; /* cannot queue: the caller closes, as for a short send */
    memcpy(stage + stage_len, buf, len);
    io_uring_prep_send(sqe, fd, stage + stage_len, len, MSG_NOSIGNAL | MSG_DONTWAIT);
    io_uring_sqe_set_data64(sqe, (uint64_t)(uintptr_t)rd | TAG_SEND);
    stage_len += len;
    sends_queued++;
    rd->inflight++;
    rd->sends++;
    rd->sent_want += len;
    return 0;
}

static void on_recv_done(struct reader *rd, int res, unsigned flags)
{
    int bid = flags & IORING_CQE_F_BUFFER ? (int)(flags >> IORING_CQE_BUFFER_SHIFT) : -1;
    if (bid >= 0)
        rb_out++;
    stats.ring_dry += res == -ENOBUFS;
    if (!(flags & IORING_CQE_F_MORE)) { /* the read is over (a multishot one too) */
        rd->inflight--;
        rd->armed = 0;
    }
    if (rd->dead) {
        if (bid >= 0)
            rb_recycle(bid);
        reader_free(rd);
        return;
    }
    if (bid >= 0 || rd->held_head >= 0 || rd->end_held) {
        /* Multishot: a chunk in a ring buffer, or the end; in order after
         * what is held. */
        if (rd->paused || rd->held_head >= 0 || rd->on_due) {
            if (bid >= 0)
                reader_hold(rd, bid, (unsigned)res);
            else if (res != -EAGAIN && res != -EINTR && res != -ECANCELED && res != -ENOBUFS)
                rd->end_held = 1, rd->end_res = res;
            if (!rd->paused && !rd->on_due)
                reader_due(rd);
            return;
        }
        if (bid >= 0) {
            rd->inflight++;
            reader_deliver_from(rd, rb_buf(bid), res);
            rb_recycle(bid);
            rd->inflight--;
            if (rd->dead)
                reader_free(rd);
            return;
        }
    }
    if (res == -ENOBUFS) { /* every buffer out: read on single-shot */
        rd->single_next = 1;
        reader_arm(rd);
        return;
    }
    if (res == -EAGAIN || res == -EINTR || res == -ECANCELED) {
        reader_arm(rd);
        return;
    }
    if (rd->paused && res > 0) {
        rd->stashed = 1;
        rd->stash_n = res;
        return;
    }
    reader_deliver(rd, res);
}

static void on_send_done(struct reader *rd, int res)
{
    rd->inflight--;
    rd->sends--;
    if (res < 0 && !rd->send_err)
        rd->send_err = res;
    else if (res > 0)
        rd->sent_done += (size_t)res;
    if (rd->dead) {
        reader_free(rd);
        return;
    }
    if (rd->sends)
        return;
    /* Whole or not at all: a short send broke the stream. */
    int err = rd->send_err ? rd->send_err : rd->sent_done != rd->sent_want ? -EAGAIN : 0;
    rd->send_err = 0;
    rd->sent_done = rd->sent_want = 0;
    if (err) {
        rd->inflight++;
        rd->cb(rd->arg, rd->fd, rd->buf, err);
        rd->inflight--;
        reader_free(rd);
    }
}

static void epoll_dispatch(void);

/* One wait on the ring; every completion dispatched. */
static int ring_wait(int64_t timeout_us)
{
    struct io_uring_cqe *cqe;
    struct __kernel_timespec ts;
    int rc;
    if (!epoll_armed) {
        struct io_uring_sqe *sqe = ring_sqe();
        if (!sqe)
            return -1;
        /* One-shot: re-armed after each epoll_wait, so an fd left ready
         * (level-triggered) completes it again at once. */
        io_uring_prep_poll_add(sqe, epfd, POLLIN);
        io_uring_sqe_set_data64(sqe, TAG_EPOLL);
        epoll_armed = 1;
    }
    ts.tv_sec = timeout_us < 0 ? 0 : timeout_us / 1000000;
    ts.tv_nsec = timeout_us < 0 ? 0 : (timeout_us % 1000000) * 1000;
    /* Each queued send completes in this very call (MSG_DONTWAIT): wait for
     * one completion more than those, or the wake-up after a reply would be
     * its send's completion and the next request cost a second call. */
    unsigned want = io_uring_cq_ready(&ring) + sends_queued + 1;
    rc = io_uring_submit_and_wait_timeout(&ring, &cqe, want, timeout_us < 0 ? NULL : &ts, NULL);
    stage_release();
    if (rc < 0 && rc != -ETIME && rc != -EINTR && rc != -EBUSY) {
        errno = -rc;
        return -1;
    }
    wake_us = loop_now_us();
    for (;;) {
        struct io_uring_cqe *batch[64];
        struct {
            uint64_t ud;
            int res;
            unsigned flags;
        } got[64];
        unsigned n = io_uring_peek_batch_cqe(&ring, batch, 64);
        if (!n)
            break;
        /* Copied out first: callbacks may submit, and a slot is reused
         * once advanced. */
        for (unsigned k = 0; k < n; k++) {
            got[k].ud = batch[k]->user_data;
            got[k].res = batch[k]->res;
            got[k].flags = batch[k]->flags;
        }
        io_uring_cq_advance(&ring, n);
        for (unsigned k = 0; k < n; k++) {
            unsigned tag = (unsigned)(got[k].ud & TAG_MASK);
            struct reader *rd = (struct reader *)(uintptr_t)(got[k].ud & ~(uint64_t)TAG_MASK);
            if (tag == TAG_RECV)
                on_recv_done(rd, got[k].res, got[k].flags);
            else if (tag == TAG_SEND)
                on_send_done(rd, got[k].res);
            else if (tag == TAG_EPOLL) {
                epoll_armed = 0;
                epoll_dispatch();
            }
        }
    }
    /* Stashes resumed since: handed over now. */
    while (due_head) {
        struct reader *rd = due_head;
        due_head = rd->due;
        rd->on_due = 0;
        if (rd->dead) {
            reader_free(rd);
        } else if (rd->stashed && !rd->paused) {
            rd->stashed = 0;
            reader_deliver(rd, rd->stash_n);
        } else if ((rd->held_head >= 0 || rd->end_held) && !rd->paused) {
            reader_drain_held(rd);
        } else {
            reader_arm(rd);
        }
    }
    return 0;
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

/* Events of the epoll set: each to its entry's callback. An event whose
 * entry was deleted by an earlier callback, or whose fd number a new entry
 * took since, is dropped (the serial differs). A level-triggered fd not
 * served this time is reported again. */
static void dispatch_events(const struct epoll_event *evs, int n)
{
    for (int e = 0; e < n; e++) {
        int fd = (int)(uint32_t)evs[e].data.u64;
        size_t k = idx_of(fd);
        if (k != SIZE_MAX && fds[k].seq == (uint32_t)(evs[e].data.u64 >> 32))
            fds[k].cb(fds[k].arg, fd, (short)evs[e].events);
    }
}

static void epoll_dispatch(void)
{
    struct epoll_event evs[64];
    int rc = epoll_wait(epfd, evs, (int)(sizeof evs / sizeof evs[0]), 0);
    if (rc > 0)
        dispatch_events(evs, rc);
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
    if (epfd < 0 && (epfd = epoll_create1(EPOLL_CLOEXEC)) < 0)
        return -1;
    if (use_ring) {
        if (ring_wait(timeout))
            return -1;
    } else {
        ts.tv_sec = (time_t)(timeout / 1000000);
        ts.tv_nsec = (long)(timeout % 1000000) * 1000;
        rc = epoll_pwait2(epfd, evs, (int)(sizeof evs / sizeof evs[0]), timeout < 0 ? NULL : &ts, NULL);
        if (rc < 0 && errno == ENOSYS) /* before Linux 5.11: ms, rounded up */
            rc = epoll_wait(epfd, evs, (int)(sizeof evs / sizeof evs[0]),
                            timeout < 0 ? -1 : (int)((timeout + 999) / 1000));
        if (rc < 0 && errno != EINTR)
            return -1;
        wake_us = loop_now_us();
        if (rc > 0)
            dispatch_events(evs, rc);
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
    if (use_ring) {
        io_uring_queue_exit(&ring); /* cancels what is in flight */
        free(rb_ring);
        free(rb_bufs);
        rb_ring = NULL;
        rb_bufs = NULL;
        rb_out = 0;
        memset(&stats, 0, sizeof stats);
        free(stage);
        stage = NULL;
        stage_len = 0;
        use_ring = epoll_armed = 0;
    }
    while (all_readers) {
        struct reader *rd = all_readers;
        all_readers = rd->all_nx;
        free(rd);
    }
    due_head = NULL;
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
