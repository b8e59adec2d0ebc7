/* store.c — see store.h.
 *
 * WAL file "wal":  header "IT2NWAL\0" u32 version(1) u32 0, then records
 *   u32 len (of seq..payload), u32 crc32c (of seq..payload), u64 seq,
 *   u8 type, payload. All little-endian. A CONFIG record of a B-spline
 *   model carries a sixth payload byte, the kind (docs/daemon.md); a POINT
 *   record whose memberships are not Q24-exact has bit 0x40 of its
 *   footprint byte set and T, I, F in Q30 (it2n.h, IT2N_MEMB_FRAC); every
 *   other record is as version 1 always had it (i, j are one byte each,
 *   so B-spline grids up to 256 x 256 fit).
 * Snapshot "snapshot": version 2 is the portable format of snapshot.c.
 *   Version 1 (raw struct dump tagged with the struct layout, written by
 *   it2nd 0.1; layout frozen in store.h) is still read when the layout
 *   matches this build's IT2N_MAX_DEGREE, so an upgrade keeps its state;
 *   it is never written.
 * Records with seq <= the snapshot's seq are skipped on replay (a crash
 * between snapshot rename and WAL reset leaves them behind). */
#include "store.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "conf.h"
#include "errs.h"

#include "it2n_proto.h"
#include "le_bytes.h"
#include "log.h"
#include "metrics.h"
#include "snapshot.h"

#define WAL_MAGIC "IT2NWAL"
#define FORMAT_VERSION 1u /* WAL; and the legacy snapshot */
#define WAL_HDR 16u
#define REC_HDR 17u /* len, crc, seq, type */
#define REC_MAX 128u
/* POINT record: T, I, F in Q30 (footprints are 0..6, so the bit is free
 * in every record older builds wrote). */
#define WAL_FINE 0x40u

static int dirfd_ = -1, walfd = -1, lockfd = -1, do_fsync = 1;
/* The operator accepted the loss of the WAL behind a damaged record
 * (store_accept_wal_loss): cut there instead of refusing to start. */
static int accept_loss;
/* seq: the last record queued; dseq: the last one durable (a failed commit
 * goes back to it, so the WAL never has a hole in its sequence). */
static uint64_t seq, dseq, wal_bytes;
/* Degraded: an I/O error left the WAL in a state that is not provably
 * durable (a failed commit, a WAL renamed into place whose directory entry
 * could not be synced). Every write is refused until a checkpoint (snapshot
 * + new WAL, everything synced) succeeds. */
static int degraded;
/* What the B-spline models add to the checkpoint reserve
 * (snapshot_max_size_bspline()): set on the loop's thread while no job is in
 * flight, read by the writer. */
static size_t bspline_reserve;
static uint8_t *qbuf;
static size_t qlen, qcap;
static int qrecs;
static struct store_stats stats;

/* The writer thread (store.h). One job at a time; the loop thread owns
 * everything above except walfd, which the job in flight owns (the loop
 * never touches it while one is). The job reports, the loop thread logs
 * and updates the store's state (store_reap). */
enum { JOB_COMMIT = 1, JOB_CHECKPOINT = 2 };
enum { J_IDLE, J_QUEUED, J_DONE };
struct job {
    int kind;
    uint8_t *buf; /* commit: the records; checkpoint: the snapshot */
    size_t len, cap;
    int recs;
    uint64_t last_seq; /* commit: seq of its last record; checkpoint: the snapshot's seq */
    uint64_t batch;
    /* results */
    int rc, err, new_wal, degrade;
    /* checkpoint: the reserve (below). want: make it if it is not held;
     * used: released for this checkpoint; held: held afterwards; rerr:
     * why it could not be made. */
    int reserve_want, reserve_used, reserve_held, reserve_rerr;
    const char *step, *degrade_what;
};
static struct job job;
static int job_state = J_IDLE; /* under wmu while the thread runs */
static int job_busy;           /* loop thread only: a job submitted, not reaped */
static int wal_ok;             /* loop thread only: walfd is open */
static uint64_t batches;       /* batch ids handed out (the gathered one is batches + 1) */
static pthread_t writer;
static int writer_on, writer_stop, evfd = -1;
static pthread_mutex_t wmu = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t wcv = PTHREAD_COND_INITIALIZER, dcv = PTHREAD_COND_INITIALIZER;
static uint64_t delayed_us; /* last job's duration, for the log */
/* The checkpoint reserve (issue 20 item 4): state_dir/reserve, a file of
 * reserve_size() bytes allocated for real. A checkpoint needs room for
 * snapshot.tmp and wal.tmp; when the WAL has filled the disk there is
 * none, and without a checkpoint the WAL never shrinks. So a checkpoint
 * that meets ENOSPC releases the reserve and tries again; once it has
 * replaced the WAL, the reserve is made again. Loop thread (the writer
 * reports through the job). */
static int reserve_held;
static int reserve_warned;
static char state_dir[256]; /* for messages */
static store_drop_fn drop_policy;

void store_set_drop_policy(store_drop_fn fn)
{
    drop_policy = fn;
}

int store_may_drop(int id, unsigned points, const char *file)
{
    char what[48];
    if (!drop_policy || drop_policy(id))
        return 1;
    if (points)
        snprintf(what, sizeof what, "%u data point(s)", points);
    else
        snprintf(what, sizeof what, "data points");
    log_err("state directory %s: %s holds %s of model %d, which the configuration does not have; add its "
            "[model:%d] section back, or keep one with 'removed = yes' to discard them (docs/daemon.md); refusing "
            "to start, files left as they are",
            state_dir, file, what, id, id);
    return 0;
}

/* Serialise a record payload; returns its length. */
static size_t encode_payload(const struct model_rec *r, uint8_t *p)
{
    size_t n = 0;
    p[n++] = (uint8_t)r->id;
    p[n++] = (uint8_t)(r->id >> 8);
    switch (r->op) {
    case MOP_CONFIG:
        p[n++] = (uint8_t)r->n;
        p[n++] = (uint8_t)r->m;
        p[n++] = (uint8_t)r->flags;
        /* The kind only when not Bezier: a Bezier-only WAL stays byte for
         * byte what older builds wrote and read. */
        if (r->kind)
            p[n++] = (uint8_t)r->kind;
        break;
    case MOP_POINT: {
        /* Memberships in Q30 (the fine layout, bit 0x40 of the footprint
         * byte) only when they need it: a point whose memberships are
         * Q24-exact is written in Q24, byte for byte what older builds
         * wrote and read. */
        int fine = 0;
        for (int c = IT2N_CH_T; c < IT2N_CH_COUNT && r->fine; c++)
            if (r->vals[c] & ((1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC)) - 1))
                fine = 1;
        p[n++] = (uint8_t)r->i;
        p[n++] = (uint8_t)r->j;
        p[n++] = (uint8_t)(r->fp | (r->replace ? 0x80u : 0u) | (fine ? WAL_FINE : 0u));
        for (int c = 0; c < IT2N_CH_COUNT; c++) {
            it2n_val v = r->vals[c];
            if (c >= IT2N_CH_T && r->fine && !fine)
                v >>= IT2N_MEMB_FRAC - IT2N_VAL_FRAC; /* exact: checked above */
            le_put64(p + n, (uint64_t)v);
            n += 8;
        }
        break;
    }
    default: break;
    }
    return n;
}

static int decode_payload(int type, const uint8_t *p, size_t len, struct model_rec *r)
{
    memset(r, 0, sizeof *r);
    if (len < 2)
        return -1;
    r->op = type;
    r->id = p[0] | p[1] << 8;
    switch (type) {
    case MOP_CONFIG:
        /* 5 bytes: a Bezier model (every version); 6: the kind follows
         * (1 = B-spline; 0 is never written in this form). */
        if (len != 5 && (len != 6 || p[5] != 1))
            return -1;
        r->n = p[2];
        r->m = p[3];
        r->flags = p[4];
        r->kind = len == 6 ? p[5] : 0;
        return 0;
    case MOP_POINT:
        if (len != 5 + 8 * IT2N_CH_COUNT)
            return -1;
        r->i = p[2];
        r->j = p[3];
        r->fp = p[4] & ~(0x80u | WAL_FINE);
        r->replace = (p[4] & 0x80u) != 0;
        r->fine = (p[4] & WAL_FINE) != 0;
        for (int c = 0; c < IT2N_CH_COUNT; c++)
            r->vals[c] = (it2n_val)le_get64(p + 5 + 8 * c);
        return 0;
    case MOP_COMMIT:
    case MOP_CLEAR: return len == 2 ? 0 : -1;
    default: return -1;
    }
}

int store_append(void *arg, const struct model_rec *rec)
{
    uint8_t rbuf[REC_HDR + REC_MAX];
    size_t plen;
    (void)arg;
    if (degraded)
        return IT2ND_ERR_DEGRADED;
    if (!wal_ok)
        return IT2ND_ERR_IO;
    plen = encode_payload(rec, rbuf + REC_HDR);
    le_put64(rbuf + 8, seq + 1);
    rbuf[16] = (uint8_t)rec->op;
    le_put32(rbuf, (uint32_t)(plen + 9));
    le_put32(rbuf + 4, it2n_crc32c(rbuf + 8, plen + 9));
    if (qlen + REC_HDR + plen > qcap) {
        size_t cap = qcap ? qcap * 2 : 4096;
        uint8_t *p = realloc(qbuf, cap);
        if (!p) {
            log_err("wal: no memory to queue a record; change refused");
            return IT2ND_ERR_NOMEM;
        }
        qbuf = p;
        qcap = cap;
    }
    memcpy(qbuf + qlen, rbuf, REC_HDR + plen);
    qlen += REC_HDR + plen;
    qrecs++;
    seq++;
    return 0;
}

int store_pending(void)
{
    return qrecs;
}

struct store_mark store_mark(void)
{
    struct store_mark m = {qlen, qrecs, seq};
    return m;
}

void store_rollback(struct store_mark m)
{
    qlen = m.len;
    qrecs = m.recs;
    seq = m.seq;
}

struct model_jmark store_jmark(void)
{
    struct model_jmark m = {qlen, qrecs, seq};
    return m;
}

void store_jrewind(struct model_jmark m)
{
    qlen = m.len;
    qrecs = m.recs;
    seq = m.seq;
}

static int write_all(int fd, const uint8_t *p, size_t len)
{
    while (len) {
        ssize_t w = write(fd, p, len);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        p += w;
        len -= (size_t)w;
    }
    return 0;
}

static void set_degraded(const char *what, int e)
{
    if (!degraded)
        log_err("store degraded: %s: %s; every write is refused (exception 04 / NACK, last_error %d) until a "
                "checkpoint (snapshot + new WAL) succeeds; retried every second",
                what, strerror(e), IT2ND_ERR_DEGRADED);
    degraded = 1;
}

int store_degraded(void)
{
    return degraded;
}

/* fdatasync (data) or fsync of a WAL file, timed: the metrics'
 * it2nd_wal_fsync_duration_seconds counts every one (any thread). */
static int wal_sync(int fd, int data)
{
    struct timespec a, b;
    int rc, e;
    clock_gettime(CLOCK_MONOTONIC, &a);
    rc = data ? fdatasync(fd) : fsync(fd);
    e = errno;
    clock_gettime(CLOCK_MONOTONIC, &b);
    metrics_wal_fsync((uint64_t)((b.tv_sec - a.tv_sec) * 1000000000LL + (b.tv_nsec - a.tv_nsec)) / 1000u, rc == 0);
    errno = e;
    return rc;
}

/* Writer side (the thread, or inline without one): the commit's I/O. */
static void run_commit(struct job *j)
{
    off_t before = lseek(walfd, 0, SEEK_END);
    j->rc = 0;
    if (before < 0 || write_all(walfd, j->buf, j->len) || (do_fsync && wal_sync(walfd, 1))) {
        j->err = errno;
        j->rc = -1;
        j->step = "WAL write/fdatasync failed";
        /* Cut off a partial write. Whether or not that works, the file is
         * no longer trusted (after a failed fdatasync the kernel may have
         * dropped pages it reported written): the next records go to a
         * new WAL, after a checkpoint. */
        if (before >= 0 && ftruncate(walfd, before) != 0)
            j->degrade_what = "truncate failed";
        j->degrade = 1;
    }
}

static void run_checkpoint(struct job *j);
static off_t reserve_size(void);
static int reserve_make(int sync);

static void run_job(struct job *j)
{
    uint64_t t0 = 0;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    t0 = (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
    j->rc = j->err = j->new_wal = j->degrade = 0;
    j->step = j->degrade_what = NULL;
    if (j->kind == JOB_COMMIT)
        run_commit(j);
    else
        run_checkpoint(j);
    clock_gettime(CLOCK_MONOTONIC, &ts);
    delayed_us = (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u - t0;
}

static void *writer_main(void *arg)
{
    (void)arg;
    pthread_mutex_lock(&wmu);
    for (;;) {
        while (job_state != J_QUEUED && !writer_stop)
            pthread_cond_wait(&wcv, &wmu);
        if (job_state != J_QUEUED)
            break;
        pthread_mutex_unlock(&wmu);
        run_job(&job);
        pthread_mutex_lock(&wmu);
        job_state = J_DONE;
        pthread_cond_broadcast(&dcv);
        uint64_t one = 1;
        if (evfd >= 0 && write(evfd, &one, sizeof one) < 0) {
            /* the counter cannot overflow here; the loop reaps anyway */
        }
    }
    pthread_mutex_unlock(&wmu);
    return NULL;
}

int store_start_writer(void)
{
    if (writer_on)
        return evfd;
    evfd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (evfd < 0)
        return -1;
    writer_stop = 0;
    /* Signals go to the loop thread only: the writer starts with all
     * blocked. */
    sigset_t all, old;
    sigfillset(&all);
    pthread_sigmask(SIG_SETMASK, &all, &old);
    int rc = pthread_create(&writer, NULL, writer_main, NULL);
    pthread_sigmask(SIG_SETMASK, &old, NULL);
    if (rc) {
        close(evfd);
        evfd = -1;
        return -1;
    }
    writer_on = 1;
    return evfd;
}

static void stop_writer(void)
{
    if (!writer_on)
        return;
    pthread_mutex_lock(&wmu);
    while (job_state == J_QUEUED)
        pthread_cond_wait(&dcv, &wmu);
    writer_stop = 1;
    pthread_cond_broadcast(&wcv);
    pthread_mutex_unlock(&wmu);
    pthread_join(writer, NULL);
    writer_on = 0;
    close(evfd);
    evfd = -1;
}

static void queue_job(void)
{
    job_busy = 1;
    if (!writer_on) {
        run_job(&job);
        job_state = J_DONE;
        return;
    }
    pthread_mutex_lock(&wmu);
    job_state = J_QUEUED;
    pthread_cond_broadcast(&wcv);
    pthread_mutex_unlock(&wmu);
}

int store_busy(void)
{
    return job_busy;
}

uint64_t store_batch(void)
{
    return batches + 1;
}

void store_wait(void)
{
    if (!writer_on)
        return;
    pthread_mutex_lock(&wmu);
    while (job_state == J_QUEUED)
        pthread_cond_wait(&dcv, &wmu);
    pthread_mutex_unlock(&wmu);
}

/* Records refused: the gathered ones never were. */
static void drop_queue(void)
{
    seq = dseq;
    qlen = 0;
    qrecs = 0;
}

int store_submit(uint64_t *batch)
{
    if (job_busy || !qrecs)
        return 0;
    if (degraded || !wal_ok) {
        log_err("wal: store degraded; %d record(s) not acknowledged", qrecs);
        drop_queue();
        return -1;
    }
    /* Swap buffers: the job takes the queue, the loop gathers into the
     * job's old buffer. */
    uint8_t *b = job.buf;
    size_t c = job.cap;
    job.kind = JOB_COMMIT;
    job.buf = qbuf;
    job.cap = qcap;
    job.len = qlen;
    job.recs = qrecs;
    job.last_seq = seq;
    job.batch = ++batches;
    qbuf = b;
    qcap = c;
    qlen = 0;
    qrecs = 0;
    if (batch)
        *batch = job.batch;
    queue_job();
    return 1;
}

static int submit_checkpoint(int durable_view)
{
    size_t size = 0;
    uint8_t *buf;
    if (job_busy)
        return 0;
    if (dirfd_ < 0) {
        log_err("snapshot failed (commit): %s", strerror(EBADF));
        return -1;
    }
    /* The durable state: the views (models.h) at dseq. Records gathered
     * meanwhile (seq > dseq) go to the new WAL after it. */
    bspline_reserve = snapshot_max_size_bspline();
    buf = snapshot_encode(dseq, &size, durable_view);
    if (!buf) {
        log_err("snapshot failed (encode): %s", strerror(ENOMEM));
        return -1;
    }
    free(job.buf);
    job.kind = JOB_CHECKPOINT;
    job.buf = buf;
    job.len = size;
    job.cap = size;
    job.recs = 0;
    job.last_seq = dseq;
    job.batch = 0;
    job.reserve_want = !reserve_held;
    queue_job();
    return 1;
}

int store_submit_checkpoint(void)
{
    return submit_checkpoint(1);
}

/* Loop side: what the checkpoint did with the reserve. */
static void reserve_reap(const struct job *j)
{
    if (j->reserve_used)
        log_notice("store: the disk is full; the checkpoint reserve (%s/reserve, %lld bytes) released for this "
                   "checkpoint",
                   state_dir, (long long)reserve_size());
    if (j->reserve_held && !reserve_held)
        log_notice("store: checkpoint reserve %s/reserve (%lld bytes) in place", state_dir, (long long)reserve_size());
    else if (!j->reserve_held && j->rc == 0 && !reserve_warned)
        log_warn("store: no room for the checkpoint reserve (%s/reserve, %lld bytes): %s; if the WAL fills the "
                 "disk, writes stay refused until space is freed; retried at every checkpoint",
                 state_dir, (long long)reserve_size(), strerror(j->reserve_rerr));
    if (j->rc == 0)
        reserve_warned = !j->reserve_held;
    reserve_held = j->reserve_held;
}

int store_reap(struct store_done *d)
{
    int done;
    memset(d, 0, sizeof *d);
    if (writer_on) {
        uint64_t cnt;
        if (evfd >= 0 && read(evfd, &cnt, sizeof cnt) < 0) {
            /* EAGAIN: nothing signalled (yet) */
        }
        pthread_mutex_lock(&wmu);
        done = job_state == J_DONE;
        if (done)
            job_state = J_IDLE;
        pthread_mutex_unlock(&wmu);
    } else {
        done = job_state == J_DONE;
        job_state = J_IDLE;
    }
    if (!done)
        return 0;
    job_busy = 0;
    d->kind = job.kind == JOB_COMMIT ? STORE_DONE_COMMIT : STORE_DONE_CHECKPOINT;
    d->batch = job.batch;
    d->ok = job.rc == 0;
    d->us = delayed_us;
    if (job.kind == JOB_COMMIT) {
        if (job.rc) {
            log_err("wal: write failed: %s; %d record(s) not acknowledged%s", strerror(job.err), job.recs + qrecs,
                    qrecs ? " (with the ones gathered meanwhile)" : "");
            if (job.degrade_what)
                log_err("wal: truncate failed");
            set_degraded(job.step, job.err);
            drop_queue();
        } else {
            wal_bytes += job.len;
            stats.records += (uint64_t)job.recs;
            stats.commits++;
            dseq = job.last_seq;
        }
        job.len = 0;
    } else {
        if (job.new_wal)
            wal_bytes = 0;
        if (job.degrade)
            set_degraded(job.degrade_what, job.err);
        reserve_reap(&job);
        if (job.rc) {
            log_err("snapshot failed (%s): %s", job.step, strerror(job.err));
        } else {
            stats.snapshots++;
            if (degraded)
                log_notice("store: checkpoint written (snapshot seq %llu, new WAL); writes accepted again",
                           (unsigned long long)job.last_seq);
            degraded = 0;
        }
        free(job.buf);
        job.buf = NULL;
        job.len = job.cap = 0;
    }
    return 1;
}

/* Synchronous: whatever is in flight finishes (its result is applied to
 * the store only: callers with replies waiting use store_reap), then the
 * queue is written and fdatasynced. */
int store_commit(void)
{
    struct store_done d;
    int rc;
    store_wait();
    store_reap(&d);
    if (!qrecs)
        return 0;
    rc = store_submit(NULL);
    if (rc < 0)
        return -1;
    store_wait();
    store_reap(&d);
    return d.ok ? 0 : -1;
}

uint64_t store_wal_bytes(void)
{
    return wal_bytes;
}

void store_get_stats(struct store_stats *st)
{
    *st = stats;
}

static int sync_dir(void)
{
    return do_fsync ? fsync(dirfd_) : 0;
}

/* Remove a temporary file after a failure (errno kept). */
static void drop_tmp(const char *name)
{
    int e = errno;
    if (unlinkat(dirfd_, name, 0) && errno != ENOENT)
        log_err("cannot remove %s/%s: %s", state_dir, name, strerror(errno));
    errno = e;
}

/* Create an empty WAL atomically (tmp + fsync + rename + fsync of the
 * directory) and append to it from now on. Before the rename a failure
 * changes nothing (the old WAL stays in use, the temporary file is
 * removed). After it, the new file is the WAL whatever happens next (the
 * old one is unlinked: appending to it would lose every record, issue 8
 * item 1); if the directory cannot be synced, the rename may not survive a
 * crash, so the store is degraded until a checkpoint succeeds. */
static int wal_reset(struct job *j)
{
    uint8_t h[WAL_HDR] = {0};
    int fd = openat(dirfd_, "wal.tmp", O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0640);
    if (fd < 0)
        return -1;
    memcpy(h, WAL_MAGIC, 8);
    le_put32(h + 8, FORMAT_VERSION);
    if (write_all(fd, h, sizeof h) || (do_fsync && wal_sync(fd, 0)) || renameat(dirfd_, "wal.tmp", dirfd_, "wal")) {
        int e = errno;
        close(fd);
        drop_tmp("wal.tmp");
        errno = e;
        return -1;
    }
    if (walfd >= 0)
        close(walfd);
    walfd = fd;
    j->new_wal = 1;
    if (sync_dir()) {
        int e = errno;
        j->degrade = 1;
        j->degrade_what = "fsync of the state directory after a new WAL was renamed into place";
        j->err = e;
        errno = e;
        return -1;
    }
    return 0;
}

/* A checkpoint: snapshot.tmp written and fsynced, renamed over snapshot,
 * directory fsynced, then a new empty WAL (wal_reset). Every failure
 * leaves the state durable: before the snapshot rename nothing changed
 * (snapshot.tmp is removed); if the directory cannot be synced after it,
 * the WAL is NOT reset (the old WAL, still in use and synced, holds every
 * record, so either snapshot plus it replays to the same state). A success
 * clears the degraded state: memory, which equals what was acknowledged,
 * is then on disk in fresh files. */
static void checkpoint_once(struct job *j)
{
    int fd = -1;
    j->rc = -1;
    j->step = "open snapshot.tmp";
    fd = openat(dirfd_, "snapshot.tmp", O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
    if (fd < 0)
        goto out;
    j->step = "write snapshot.tmp";
    if (write_all(fd, j->buf, j->len))
        goto out_tmp;
    j->step = "fsync snapshot.tmp";
    if (do_fsync && fsync(fd))
        goto out_tmp;
    j->step = "close snapshot.tmp";
    if (close(fd)) {
        fd = -1;
        goto out_tmp;
    }
    fd = -1;
    j->step = "rename snapshot.tmp";
    if (renameat(dirfd_, "snapshot.tmp", dirfd_, "snapshot"))
        goto out_tmp;
    j->step = "fsync the state directory after the snapshot rename (WAL kept)";
    if (sync_dir())
        goto out;
    /* The snapshot now holds everything: start an empty WAL. A crash
     * before this leaves old records, skipped by seq on replay. */
    j->step = "new WAL";
    if (wal_reset(j))
        goto out;
    j->rc = 0;
    return;
out_tmp:
    if (fd >= 0) {
        int e = errno;
        close(fd);
        errno = e;
    }
    drop_tmp("snapshot.tmp");
out:
    if (!j->err)
        j->err = errno;
}

/* The largest snapshot CONF_MAX_MODELS models can give, a new WAL, and
 * room for the filesystem's own blocks, in whole 4 KiB blocks. */
static off_t reserve_size(void)
{
    size_t n = snapshot_max_size(CONF_MAX_MODELS) + bspline_reserve + WAL_HDR + ((size_t)64 << 10);
    return (off_t)((n + 4095) & ~(size_t)4095);
}

/* Make the reserve (or complete it): 0 or an errno. The blocks are
 * allocated for real: fallocate, or zeros written where the filesystem
 * has no fallocate (never a sparse file). sync: fsync it too. */
static int reserve_make(int sync)
{
    const off_t want = reserve_size();
    struct stat st;
    int e = 0, fd = openat(dirfd_, "reserve", O_WRONLY | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0640);
    if (fd < 0)
        return errno;
    if (fstat(fd, &st) == 0 && st.st_size == want && (off_t)st.st_blocks * 512 >= want) {
        close(fd);
        return 0;
    }
    if (fallocate(fd, 0, 0, want)) {
        e = errno;
        if (e == EOPNOTSUPP || e == ENOSYS) {
            static const uint8_t zero[4096];
            e = 0;
            for (off_t off = 0; !e && off < want; off += (off_t)sizeof zero)
                if (pwrite(fd, zero, sizeof zero, off) != (ssize_t)sizeof zero)
                    e = errno ? errno : ENOSPC;
        }
    }
    if (!e && sync && do_fsync && fsync(fd))
        e = errno;
    close(fd);
    return e;
}

static int full(int e)
{
    return e == ENOSPC || e == EDQUOT;
}

/* Writer side: a checkpoint; on a full disk, once more with the reserve
 * released; then the reserve made again if it is not held. */
static void run_checkpoint(struct job *j)
{
    j->reserve_used = 0;
    j->reserve_held = !j->reserve_want;
    j->reserve_rerr = 0;
    checkpoint_once(j);
    if (j->rc && full(j->err) && !j->degrade && unlinkat(dirfd_, "reserve", 0) == 0) {
        j->reserve_used = 1;
        j->reserve_held = 0;
        j->err = 0;
        j->step = NULL;
        checkpoint_once(j);
    }
    if (j->rc == 0 && !j->reserve_held) {
        j->reserve_rerr = reserve_make(1);
        j->reserve_held = j->reserve_rerr == 0;
    }
}

int store_snapshot(void)
{
    struct store_done d;
    if (store_commit()) {
        log_err("snapshot failed (commit): %s", strerror(EIO));
        return -1;
    }
    /* Everything queued is durable now: memory is the durable state. */
    if (submit_checkpoint(0) < 0)
        return -1;
    store_wait();
    store_reap(&d);
    return d.ok ? 0 : -1;
}

/* The snapshot is read whole; it holds at most CONF_MAX_MODELS models of
 * bounded size, far below this limit (plus what the configured B-spline
 * grids may hold), so a larger file is not ours. */
#define SNAPSHOT_FILE_MAX (((off_t)64 << 20) + (off_t)snapshot_max_size_bspline())

/* Read a whole file. NULL with errno ENOENT when it does not exist, EFBIG
 * over max, or the I/O error; the caller decides (and logs) what follows. */
static uint8_t *read_file(const char *name, off_t max, size_t *len)
{
    int fd = openat(dirfd_, name, O_RDONLY | O_CLOEXEC);
    struct stat st = {0};
    uint8_t *buf;
    size_t got = 0;
    if (fd < 0)
        return NULL;
    if (fstat(fd, &st) || st.st_size > max) {
        int e = errno;
        if (st.st_size > max)
            e = EFBIG;
        close(fd);
        errno = e;
        return NULL;
    }
    buf = malloc((size_t)st.st_size + 1);
    while (buf && got < (size_t)st.st_size) {
        ssize_t n = read(fd, buf + got, (size_t)st.st_size - got);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {
            int e = n == 0 ? EIO : errno; /* shrank under us: treat as an error */
            free(buf);
            buf = NULL;
            errno = e;
            break;
        }
        got += (size_t)n;
    }
    if (!buf && errno == 0)
        errno = ENOMEM;
    close(fd);
    *len = (size_t)st.st_size;
    return buf;
}

/* Keep a damaged file as evidence: rename it to NAME.damaged-<UTC time>
 * (-N appended if taken) and sync the directory. The daemon then refuses
 * to start, and keeps refusing while such a file is in the state directory
 * (store_open): an operator decides what to do (docs/daemon.md, "Recovery
 * after damage"). Returns -1 always (the caller's return value). */
static int keep_damaged(const char *name, const char *why)
{
    char aside[96], stamp[32];
    time_t now = time(NULL);
    struct tm tm;
    int n = 0;
    gmtime_r(&now, &tm);
    strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
    snprintf(aside, sizeof aside, "%s.damaged-%s", name, stamp);
    while (faccessat(dirfd_, aside, F_OK, AT_SYMLINK_NOFOLLOW) == 0 && n < 100)
        snprintf(aside, sizeof aside, "%s.damaged-%s-%d", name, stamp, ++n);
    if (renameat(dirfd_, name, dirfd_, aside)) {
        log_err("%s/%s is damaged (%s) and cannot be renamed aside: %s; refusing to start, file left as it is",
                state_dir, name, why, strerror(errno));
        return -1;
    }
    if (sync_dir())
        log_err("fsync of %s after renaming %s aside: %s", state_dir, name, strerror(errno));
    log_err("%s/%s is damaged (%s): kept as %s/%s; refusing to start: serving without it would serve a state that "
            "never existed. Recovery: docs/daemon.md, \"Recovery after damage\"",
            state_dir, name, why, state_dir, aside);
    return -1;
}

/* Before the WAL is cut after its last good record, keep the bytes cut
 * off as NAME.cut-<UTC time> (fsynced): a torn last commit after a crash,
 * or records behind a damaged one that an operator may still want. Not a
 * reason to refuse the start (unlike .damaged-), but if they cannot be
 * kept the WAL is not cut and the start refused. Returns 0 or -1. */
static int keep_tail(uint64_t good, uint64_t total)
{
    char name[64], stamp[32];
    time_t now = time(NULL);
    struct tm tm;
    uint8_t buf[4096];
    int in, out, n = 0, rc = -1;
    gmtime_r(&now, &tm);
    strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &tm);
    snprintf(name, sizeof name, "wal.cut-%s", stamp);
    while (faccessat(dirfd_, name, F_OK, AT_SYMLINK_NOFOLLOW) == 0 && n < 100)
        snprintf(name, sizeof name, "wal.cut-%s-%d", stamp, ++n);
    in = openat(dirfd_, "wal", O_RDONLY | O_CLOEXEC);
    out = openat(dirfd_, name, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0640);
    if (in >= 0 && out >= 0) {
        uint64_t off = good;
        rc = 0;
        while (rc == 0 && off < total) {
            size_t want = total - off < sizeof buf ? (size_t)(total - off) : sizeof buf;
            ssize_t got = pread(in, buf, want, (off_t)off);
            if (got < 0 && errno == EINTR)
                continue;
            if (got <= 0 || write_all(out, buf, (size_t)got))
                rc = -1;
            else
                off += (uint64_t)got;
        }
        if (rc == 0 && ((do_fsync && fsync(out)) || sync_dir()))
            rc = -1;
    }
    int e = errno;
    if (in >= 0)
        close(in);
    if (out >= 0)
        close(out);
    if (rc) {
        if (out >= 0)
            unlinkat(dirfd_, name, 0);
        log_err("wal: cannot keep the %llu byte(s) to cut off in %s/%s: %s; refusing to start, WAL left as it is",
                (unsigned long long)(total - good), state_dir, name, strerror(e));
        return -1;
    }
    log_notice("wal: the %llu byte(s) cut off after offset %llu are kept in %s/%s", (unsigned long long)(total - good),
               (unsigned long long)good, state_dir, name);
    return 0;
}

/* Version 1: the data set of a raw record, re-put and (solve) re-solved
 * into md. On error md is unchanged. */
static int v1_rebuild(struct model *md, const struct store_v1_it2n_dataset *src, int solve, it2n_errinfo *err)
{
    it2n_dataset *ds = malloc(sizeof *ds);
    it2n_model *mdl = malloc(sizeof *mdl);
    int rc = IT2N_ERR_STATE;
    memset(err, 0, sizeof *err);
    err->code = rc;
    if (ds && mdl)
        rc = it2n_dataset_init(ds, src->n, src->m, src->flags, err);
    for (unsigned i = 0; rc == IT2N_OK && i <= ds->n; i++)
        for (unsigned j = 0; rc == IT2N_OK && j <= ds->m; j++)
            for (unsigned fp = 0; rc == IT2N_OK && fp < IT2N_FP_COUNT; fp++)
                if (src->present[i][j] & (1u << fp))
                    rc = it2n_dataset_put(ds, i, j, fp, src->values[i][j][fp], false, err);
    if (rc == IT2N_OK) {
        it2n_model_init(mdl);
        if (solve)
            rc = it2n_model_solve(mdl, ds, err);
    }
    if (rc == IT2N_OK) {
        md->ds = *ds;
        md->mdl = *mdl;
    }
    free(ds);
    free(mdl);
    return rc;
}

/* Load the snapshot into the models; *seqp = the seq it covers (0 none).
 * A snapshot whose contents do not validate is ignored (logged); one that
 * cannot be read at all (I/O error, over the size limit) returns -1: the
 * daemon must not start and later overwrite it with less. */
static int load_snapshot(uint64_t *seqp)
{
    size_t len = 0;
    uint8_t *buf = read_file("snapshot", SNAPSHOT_FILE_MAX, &len);
    uint64_t sseq = 0;
    *seqp = 0;
    if (!buf) {
        if (errno == ENOENT)
            return 0;
        if (errno == EFBIG)
            log_err("snapshot: %s/snapshot is larger than the limit of %lld bytes (not a snapshot of this "
                    "daemon?); refusing to start, file left as it is",
                    state_dir, (long long)SNAPSHOT_FILE_MAX);
        else
            log_err("snapshot: cannot read %s/snapshot: %s; refusing to start, file left as it is", state_dir,
                    strerror(errno));
        return -1;
    }
    if (len < 36 || memcmp(buf, SNAPSHOT_MAGIC, 8)) {
        log_err("snapshot: not a snapshot (%zu bytes)", len);
        free(buf);
        return keep_damaged("snapshot", "not a snapshot");
    }
    if (le_get32(buf + 8) == SNAPSHOT_VERSION || le_get32(buf + 8) == SNAPSHOT_VERSION_BEZIER ||
        le_get32(buf + 8) == SNAPSHOT_VERSION_FINE) {
        int drc = snapshot_decode(buf, len, &sseq);
        free(buf);
        if (drc == SNAPSHOT_UNCONFIGURED)
            return -1;
        if (drc == SNAPSHOT_NOMEM) {
            log_err("snapshot: out of memory while loading %s/snapshot; refusing to start, file left as it is",
                    state_dir);
            return -1;
        }
        if (drc)
            return keep_damaged("snapshot", drc == SNAPSHOT_BAD_MODEL ? "a model record does not validate"
                                                                      : "checksum or structure");
        *seqp = sseq;
        return 0;
    }
    if (le_get32(buf + 8) != FORMAT_VERSION || le_get32(buf + 12) != store_v1_layout_tag()) {
        log_err("snapshot: %s/snapshot is version %u / layout %08x, which this build cannot read; refusing to "
                "start, file left as it is",
                state_dir, le_get32(buf + 8), le_get32(buf + 12));
        free(buf);
        return -1;
    }
    uint32_t n = le_get32(buf + 24);
    if (len != 32 + (size_t)n * sizeof(struct store_v1_snap_model) + 4 ||
        le_get32(buf + len - 4) != it2n_crc32c(buf, len - 4)) {
        log_err("snapshot: truncated or checksum mismatch (%zu bytes)", len);
        free(buf);
        return keep_damaged("snapshot", "truncated or checksum mismatch");
    }
    sseq = le_get64(buf + 16);
    for (uint32_t k = 0; k < n; k++) {
        struct store_v1_snap_model sm;
        it2n_errinfo err;
        memcpy(&sm, buf + 32 + (size_t)k * sizeof sm, sizeof sm);
        struct model *md = models_by_id(sm.id);
        if (!md) {
            unsigned pts = 0; /* counted over the whole array: n, m are not trusted yet */
            for (unsigned i = 0; i < IT2N_DIM; i++)
                for (unsigned j = 0; j < IT2N_DIM; j++)
                    pts += (unsigned)__builtin_popcount(sm.ds.present[i][j]);
            if (pts && !store_may_drop(sm.id, pts, "snapshot")) {
                free(buf);
                return -1;
            }
            log_warn("snapshot: model %d no longer configured; dropped", sm.id);
            continue;
        }
        if (md->kind != MODEL_BEZIER) {
            /* version 1 models are all Bezier */
            log_err("snapshot: model %d is a Bezier model in the legacy snapshot, but [model:%d] says kind = %s; set "
                    "the kind back (or remove the model with 'removed = yes'); refusing to start, files left as "
                    "they are",
                    sm.id, sm.id, models_kind_name(md->kind));
            free(buf);
            return -1;
        }
        /* Never trust stored derived state: rebuild the data set entry by
         * entry through the core's checks and solve it again, as version 2
         * does (the stored control nets are ignored). */
        if (sm.state < IT2N_REGMAP_STATE_EMPTY || sm.state > IT2N_REGMAP_STATE_FAILED ||
            v1_rebuild(md, &sm.ds, sm.state == IT2N_REGMAP_STATE_SOLVED, &err) != IT2N_OK) {
            log_err("snapshot: model %d fails validation (%s)", sm.id, it2n_strerror(err.code));
            free(buf);
            return keep_damaged("snapshot", "a model record does not validate");
        }
        md->state = sm.state;
        md->gen = sm.gen;
        md->points_rx = sm.points_rx;
        md->solves = sm.solves;
        memcpy(md->mb.upload, sm.upload, sizeof md->mb.upload);
    }
    log_notice("snapshot: legacy version 1, %u model(s) loaded, seq %llu; the next one is written as version %u", n,
               (unsigned long long)sseq, SNAPSHOT_VERSION_BEZIER);
    free(buf);
    *seqp = sseq;
    return 0;
}

/* Replay the WAL after sseq, streaming: a buffer of WAL_CHUNK bytes that
 * always holds a whole record when the file has one, so memory is bounded
 * and there is no limit on the file size (security finding 9). *good = the
 * length of the valid prefix (0: no usable WAL, create one), *total = the
 * file size. Returns -1 when the file exists but cannot be read: the daemon
 * then refuses to start and the file stays as it is. */
#define WAL_CHUNK ((size_t)64 << 10)
#define REC_WIRE_MAX (8u + 9u + REC_MAX) /* len, crc, then seq..payload */

/* Is there a whole, valid record at p (avail bytes): length in range, CRC,
 * decodable, seq > after? *rseq and *wire (its length on disk) filled. */
static int rec_valid(const uint8_t *p, size_t avail, uint64_t after, uint64_t *rseq, size_t *wire)
{
    struct model_rec rec;
    if (avail < 8)
        return 0;
    uint32_t rlen = le_get32(p);
    if (rlen < 9 || rlen > 9 + REC_MAX || 8u + rlen > avail || le_get32(p + 4) != it2n_crc32c(p + 8, rlen) ||
        decode_payload(p[16], p + REC_HDR, rlen - 9, &rec) || le_get64(p + 8) <= after)
        return 0;
    *rseq = le_get64(p + 8);
    *wire = 8u + rlen;
    return 1;
}

/* Damage at offset from (the record there does not validate, or breaks
 * the sequence after seq `after`): is anything valid behind it? Scans
 * every offset from `start` on (from + 1, or from itself when the record
 * there is valid but out of sequence) for a valid record with a later
 * seq, then counts the run of consecutive records from there (for the
 * log). Returns 1
 * (found: *at, *first, *last, *count), 0 (nothing valid follows: a torn
 * tail) or -1 (read error, logged). A record torn by a crash is the last
 * thing written; one that valid records follow was acknowledged, or sits
 * before records that were (issue 20 item 3). */
static int find_after_damage(int fd, uint64_t from, uint64_t start, uint64_t total, uint64_t after, uint64_t *at,
                             uint64_t *first, uint64_t *last, uint64_t *count)
{
    const size_t cap = WAL_CHUNK + REC_WIRE_MAX;
    uint8_t *b = malloc(cap);
    uint64_t base = start, rs = 0;
    size_t wire = 0;
    int found = 0;
    *count = 0;
    if (!b) {
        log_err("wal: no memory to examine the damage at offset %llu; refusing to start", (unsigned long long)from);
        return -1;
    }
    /* Find the first valid record after the damage; then walk the run. */
    while (base < total) {
        size_t want = total - base < cap ? (size_t)(total - base) : cap, got = 0;
        while (got < want) {
            ssize_t n = pread(fd, b + got, want - got, (off_t)(base + got));
            if (n < 0 && errno == EINTR)
                continue;
            if (n <= 0) {
                log_err("wal: read error in %s/wal at offset %llu: %s; refusing to start, file left as it is",
                        state_dir, (unsigned long long)(base + got), n < 0 ? strerror(errno) : "file shrank");
                free(b);
                return -1;
            }
            got += (size_t)n;
        }
        size_t lim = got == cap ? WAL_CHUNK : got;
        if (!found) {
            for (size_t k = 0; k < lim; k++)
                if (rec_valid(b + k, got - k, after, &rs, &wire)) {
                    found = 1;
                    *at = base + k;
                    *first = *last = rs;
                    *count = 1;
                    base += k + wire;
                    break;
                }
            if (!found) {
                base += lim;
                continue;
            }
        } else {
            size_t k = 0;
            while (k < lim && rec_valid(b + k, got - k, *last, &rs, &wire) && rs == *last + 1) {
                *last = rs;
                ++*count;
                k += wire;
            }
            if (k < lim)
                break; /* the run ends here */
            base += k;
        }
    }
    free(b);
    return found;
}

/* The WAL does not validate from offset off on (why). Nothing valid
 * behind it: a torn tail, the last commit cut short by a crash or power cut
 * before it was acknowledged; it is cut off (kept in wal.cut-*). Valid
 * records behind it: damage inside the log, acknowledged records would be
 * lost, so the start is refused and the file left as it is, unless the
 * operator accepted the loss (store_accept_wal_loss). Returns 0 (cut
 * here) or -1 (logged). */
static int wal_damage(int fd, const char *why, int in_seq, uint64_t off, uint64_t total)
{
    uint64_t at = 0, first = 0, last = 0, count = 0;
    int f = find_after_damage(fd, off, in_seq ? off + 1 : off, total, seq, &at, &first, &last, &count);
    if (f < 0)
        return -1;
    if (f == 0) {
        log_err("wal: %s at offset %llu; %llu byte(s) dropped (a torn last commit: nothing valid follows it)", why,
                (unsigned long long)off, (unsigned long long)(total - off));
        return 0;
    }
    if (!accept_loss) {
        log_err("wal: %s/wal is damaged inside the log: %s at offset %llu after record %llu, but valid records "
                "follow it (%llu record(s), seq %llu..%llu, from offset %llu): acknowledged records would be lost; "
                "refusing to start, file left as it is. Recovery: docs/daemon.md, \"Damage inside the WAL\"",
                state_dir, why, (unsigned long long)off, (unsigned long long)seq, (unsigned long long)count,
                (unsigned long long)first, (unsigned long long)last, (unsigned long long)at);
        return -1;
    }
    log_warn("wal: --accept-wal-loss: %s at offset %llu after record %llu; the operator accepts the loss of every "
             "record from there on (%llu valid record(s) behind the damage, seq %llu..%llu, and %llu byte(s) in "
             "all; kept in wal.cut-*)",
             why, (unsigned long long)off, (unsigned long long)seq, (unsigned long long)count,
             (unsigned long long)first, (unsigned long long)last, (unsigned long long)(total - off));
    return 0;
}

static int replay_wal(uint64_t sseq, uint64_t *good, uint64_t *total)
{
    int fd = openat(dirfd_, "wal", O_RDONLY | O_CLOEXEC);
    struct stat st;
    uint8_t *buf = NULL;
    size_t have = 0, pos = 0; /* bytes in buf; next record at buf[pos] */
    uint64_t base = 0;        /* file offset of buf[0] */
    uint64_t off = 0;         /* the record being read */
    unsigned long long applied = 0, skipped = 0, failed = 0;
    int eof = 0, rc = -1, damaged = 0, seq_break = 0;
    const char *why = NULL; /* the damage at off */
    *good = *total = 0;
    if (fd < 0) {
        if (errno == ENOENT)
            return 0;
        log_err("wal: cannot open %s/wal: %s; refusing to start, file left as it is", state_dir, strerror(errno));
        return -1;
    }
    if (fstat(fd, &st) || !(buf = malloc(WAL_CHUNK))) {
        log_err("wal: cannot read %s/wal: %s; refusing to start, file left as it is", state_dir, strerror(errno));
        goto out;
    }
    *total = (uint64_t)st.st_size;
    seq = sseq;
    for (;;) {
        /* Refill so that a whole record is in the buffer unless at EOF. */
        if (!eof && have - pos < REC_WIRE_MAX) {
            memmove(buf, buf + pos, have - pos);
            base += pos;
            have -= pos;
            pos = 0;
            while (!eof && have < WAL_CHUNK) {
                ssize_t n = read(fd, buf + have, WAL_CHUNK - have);
                if (n < 0 && errno == EINTR)
                    continue;
                if (n < 0) {
                    log_err("wal: read error in %s/wal at offset %llu: %s; refusing to start, file left as it is",
                            state_dir, (unsigned long long)(base + have), strerror(errno));
                    goto out;
                }
                if (n == 0)
                    eof = 1;
                have += (size_t)n;
            }
        }
        off = base + pos;
        if (off == 0) {
            if (have < WAL_HDR || memcmp(buf, WAL_MAGIC, 8) || le_get32(buf + 8) != FORMAT_VERSION) {
                /* Never dropped and overwritten (issue 8 item 4): its
                 * records may be intact behind a flipped header byte. */
                log_err("wal: bad header (%llu bytes)", (unsigned long long)*total);
                damaged = 1;
                goto out;
            }
            pos = WAL_HDR;
            continue;
        }
        if (have == pos)
            break; /* the end */
        if (have - pos < REC_HDR) {
            why = "truncated record";
            break;
        }
        const uint8_t *r = buf + pos;
        uint32_t rlen = le_get32(r);
        struct model_rec rec;
        it2n_errinfo err;
        if (rlen < 9 || rlen > 9 + REC_MAX || 8u + rlen > have - pos) {
            why = "truncated record";
            break;
        }
        if (le_get32(r + 4) != it2n_crc32c(r + 8, rlen)) {
            why = "checksum mismatch";
            break;
        }
        uint64_t rseq = le_get64(r + 8);
        if (decode_payload(r[16], r + REC_HDR, rlen - 9, &rec)) {
            why = "undecodable record";
            break;
        }
        if (rseq <= sseq) {
            pos += 8u + rlen;
            skipped++;
            continue;
        }
        if (rseq != seq + 1 && seq == sseq) {
            /* The first record after the snapshot must follow it: a hole
             * means the state it builds on is missing (a snapshot deleted,
             * or an older one restored under a newer WAL). */
            log_err("wal: first record after the snapshot (seq %llu) is seq %llu: records %llu..%llu are missing "
                    "(snapshot deleted or replaced?); refusing to start, files left as they are",
                    (unsigned long long)sseq, (unsigned long long)rseq, (unsigned long long)sseq + 1,
                    (unsigned long long)rseq - 1);
            goto out;
        }
        if (rseq != seq + 1) {
            /* Inside one WAL the sequence has no holes (a failed commit
             * rolls it back): records are missing here. */
            why = "sequence break (records missing)";
            seq_break = 1;
            break;
        }
        pos += 8u + rlen;
        if (rec.op == MOP_POINT && !models_by_id(rec.id) && !store_may_drop(rec.id, 0, "wal"))
            goto out;
        if (models_apply(&rec, &err) != IT2N_OK) {
            log_warn("wal: record %llu (model %d, op %d) no longer applies: %s", (unsigned long long)rseq, rec.id,
                     rec.op, it2n_strerror(err.code));
            failed++;
        } else {
            applied++;
        }
        seq = rseq;
    }
    if (why && wal_damage(fd, why, !seq_break, off, *total) < 0)
        goto out;
    *good = base + pos;
    log_info("wal: %llu record(s) replayed, %llu already in the snapshot, %llu failed (%llu bytes)", applied, skipped,
             failed, (unsigned long long)*good);
    stats.dropped += *total - *good;
    rc = 0;
out:
    free(buf);
    close(fd);
    if (damaged)
        return keep_damaged("wal", "bad header");
    return rc;
}

/* The state directory belongs to one daemon: an exclusive flock on
 * state_dir/lock, taken before anything else in it is read or written and
 * held until exit (the kernel drops it when the process dies, kill -9
 * included). A second daemon exits here, having touched nothing. */
static int take_lock(void)
{
    char pid[32] = "";
    lockfd = openat(dirfd_, "lock", O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0640);
    if (lockfd < 0) {
        log_err("state directory %s: cannot open the lock file %s/lock: %s", state_dir, state_dir, strerror(errno));
        return -1;
    }
    if (flock(lockfd, LOCK_EX | LOCK_NB)) {
        int e = errno;
        ssize_t n = pread(lockfd, pid, sizeof pid - 1, 0);
        pid[n > 0 ? n : 0] = 0;
        pid[strcspn(pid, "\n")] = 0;
        if (e == EWOULDBLOCK)
            log_err("state directory %s is in use by another it2nd (pid %s, lock %s/lock); not starting, nothing "
                    "read or written",
                    state_dir, pid[0] ? pid : "unknown", state_dir);
        else
            log_err("state directory %s: cannot lock %s/lock: %s", state_dir, state_dir, strerror(e));
        close(lockfd);
        lockfd = -1;
        return -1;
    }
    int len = snprintf(pid, sizeof pid, "%ld\n", (long)getpid());
    if (ftruncate(lockfd, 0) || pwrite(lockfd, pid, (size_t)len, 0) != len)
        log_warn("state directory %s: cannot write the pid into %s/lock: %s", state_dir, state_dir, strerror(errno));
    return 0;
}

/* A damaged file kept by an earlier start (keep_damaged) is still in the
 * state directory: refuse until an operator has dealt with it. */
static int damaged_present(void)
{
    int fd = openat(dirfd_, ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    DIR *d = fd >= 0 ? fdopendir(fd) : NULL;
    const struct dirent *e;
    int found = 0;
    if (!d) {
        if (fd >= 0)
            close(fd);
        log_err("state directory %s: cannot list: %s", state_dir, strerror(errno));
        return 1;
    }
    while ((e = readdir(d)) != NULL)
        if (strstr(e->d_name, ".damaged-")) {
            log_err("state directory %s holds %s/%s, a damaged file kept by an earlier start; not starting until "
                    "an operator has dealt with it (docs/daemon.md, \"Recovery after damage\")",
                    state_dir, state_dir, e->d_name);
            found = 1;
        }
    closedir(d);
    return found;
}

static void close_all(void)
{
    if (walfd >= 0)
        close(walfd);
    if (dirfd_ >= 0)
        close(dirfd_);
    if (lockfd >= 0)
        close(lockfd); /* releases the lock */
    walfd = dirfd_ = lockfd = -1;
    wal_ok = 0;
}

/* The state directory's own entry is durable only once its parent has
 * been fsynced after the mkdir (a power cut could otherwise take the whole
 * directory, and every acknowledged record in it, away). Done at every
 * start: an earlier start may have died between the mkdir and this. */
static int sync_parent(const char *dir)
{
    char *parent = strdup(dir), *slash;
    size_t n = strlen(dir);
    int fd, rc = -1, e = ENOMEM;
    if (parent) {
        while (n > 1 && parent[n - 1] == '/')
            parent[--n] = 0;
        slash = strrchr(parent, '/');
        if (slash)
            slash[slash == parent] = 0; /* "/x" -> "/" */
        fd = open(slash ? parent : ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        rc = fd < 0 ? -1 : fsync(fd);
        e = errno;
        if (fd >= 0)
            close(fd);
        free(parent);
    }
    errno = e;
    return rc;
}

void store_set_fsync(int on)
{
    /* Under the writer's lock: the writer reads do_fsync in the job it
     * takes after this (a reload runs with no job in progress). */
    pthread_mutex_lock(&wmu);
    do_fsync = on;
    pthread_mutex_unlock(&wmu);
}

int store_open(const char *dir, int fsync_on)
{
    uint64_t good, total;
    do_fsync = fsync_on;
    degraded = 0;
    seq = dseq = 0;
    snprintf(state_dir, sizeof state_dir, "%s", dir);
    int made = mkdir(dir, 0750) == 0;
    if (!made && errno != EEXIST) {
        log_err("state directory %s: %s", dir, strerror(errno));
        return -1;
    }
    if (do_fsync && sync_parent(dir)) {
        /* Fatal when the directory is new: nothing in it would be durable. */
        if (made) {
            log_err("state directory %s: created, but its parent directory cannot be fsynced: %s", dir,
                    strerror(errno));
            return -1;
        }
        log_warn("state directory %s: cannot fsync its parent directory: %s", dir, strerror(errno));
    }
    dirfd_ = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dirfd_ < 0) {
        log_err("state directory %s: %s", dir, strerror(errno));
        return -1;
    }
    if (take_lock() || damaged_present() || load_snapshot(&seq) || replay_wal(seq, &good, &total)) {
        close_all();
        return -1;
    }
    /* Temporary files of a checkpoint a crash interrupted: never renamed
     * into place, so never part of the state (not evidence). */
    for (int k = 0; k < 2; k++) {
        const char *tmp = k ? "wal.tmp" : "snapshot.tmp";
        if (unlinkat(dirfd_, tmp, 0) == 0)
            log_notice("removed %s/%s left by an interrupted checkpoint", dir, tmp);
    }
    if (good >= WAL_HDR) {
        if (good < total && keep_tail(good, total)) {
            close_all();
            return -1;
        }
        walfd = openat(dirfd_, "wal", O_WRONLY | O_APPEND | O_CLOEXEC);
        if (walfd < 0 || (good < total && ftruncate(walfd, (off_t)good))) {
            log_err("wal: cannot reopen: %s", strerror(errno));
            close_all();
            return -1;
        }
        wal_bytes = good - WAL_HDR;
    } else {
        struct job j0;
        memset(&j0, 0, sizeof j0);
        if (wal_reset(&j0)) {
            log_err("wal: cannot create in %s: %s", dir, strerror(errno));
            close_all();
            return -1;
        }
        wal_bytes = 0;
    }
    dseq = seq;
    wal_ok = 1;
    /* The checkpoint reserve, kept across restarts (a restart on a disk
     * the WAL filled needs it as much). Not having it is no reason to
     * refuse the start: logged, made at the next checkpoint if it can. */
    bspline_reserve = snapshot_max_size_bspline();
    int re = reserve_make(1);
    reserve_held = re == 0;
    reserve_warned = !reserve_held;
    if (re)
        log_warn("store: no room for the checkpoint reserve (%s/reserve, %lld bytes): %s; if the WAL fills the disk, "
                 "writes stay refused until space is freed; retried at every checkpoint",
                 dir, (long long)reserve_size(), strerror(re));
    else if (sync_dir())
        log_warn("store: fsync of %s after making the checkpoint reserve: %s", dir, strerror(errno));
    return 0;
}

void store_accept_wal_loss(int on)
{
    accept_loss = on;
}

int store_chown(unsigned uid, unsigned gid)
{
    static const char *const files[] = {"wal", "snapshot", "lock", "reserve"};
    if (fchown(dirfd_, (uid_t)uid, (gid_t)gid))
        return -1;
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++)
        if (fchownat(dirfd_, files[k], (uid_t)uid, (gid_t)gid, AT_SYMLINK_NOFOLLOW) && errno != ENOENT)
            return -1;
    return 0;
}

void store_close(void)
{
    store_commit();
    stop_writer();
    close_all();
    free(qbuf);
    free(job.buf);
    qbuf = job.buf = NULL;
    qlen = qcap = 0;
    job.len = job.cap = 0;
    job_state = J_IDLE;
    job_busy = 0;
}
