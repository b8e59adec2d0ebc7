/* store.c — see store.h.
 *
 * WAL file "wal":  header "IT2NWAL\0" u32 version(1) u32 0, then records
 *   u32 len (of seq..payload), u32 crc32c (of seq..payload), u64 seq,
 *   u8 type, payload. All little-endian.
 * Snapshot "snapshot": version 2 is the portable format of snapshot.c.
 *   Version 1 (raw struct dump tagged with the struct layout, written by
 *   it2nd 0.1; layout frozen in store.h) is still read when the layout
 *   matches this build's IT2N_MAX_DEGREE, so an upgrade keeps its state;
 *   it is never written.
 * Records with seq <= the snapshot's seq are skipped on replay (a crash
 * between snapshot rename and WAL reset leaves them behind). */
#include "store.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "it2n_proto.h"
#include "le_bytes.h"
#include "log.h"
#include "snapshot.h"

#define WAL_MAGIC "IT2NWAL"
#define FORMAT_VERSION 1u  /* WAL; and the legacy snapshot */
#define WAL_HDR 16u
#define REC_HDR 17u        /* len, crc, seq, type */
#define REC_MAX 128u

static int dirfd_ = -1, walfd = -1, do_fsync = 1;
static uint64_t seq, wal_bytes;
static uint8_t *qbuf;
static size_t qlen, qcap;
static int qrecs;
static struct store_stats stats;
static char state_dir[256]; /* for messages */

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
        break;
    case MOP_POINT:
        p[n++] = (uint8_t)r->i;
        p[n++] = (uint8_t)r->j;
        p[n++] = (uint8_t)(r->fp | (r->replace ? 0x80u : 0u));
        for (int c = 0; c < IT2N_CH_COUNT; c++) {
            put64(p + n, (uint64_t)r->vals[c]);
            n += 8;
        }
        break;
    default:
        break;
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
        if (len != 5)
            return -1;
        r->n = p[2];
        r->m = p[3];
        r->flags = p[4];
        return 0;
    case MOP_POINT:
        if (len != 5 + 8 * IT2N_CH_COUNT)
            return -1;
        r->i = p[2];
        r->j = p[3];
        r->fp = p[4] & 0x7Fu;
        r->replace = (p[4] & 0x80u) != 0;
        for (int c = 0; c < IT2N_CH_COUNT; c++)
            r->vals[c] = (it2n_val)get64(p + 5 + 8 * c);
        return 0;
    case MOP_COMMIT:
    case MOP_CLEAR:
        return len == 2 ? 0 : -1;
    default:
        return -1;
    }
}

int store_append(void *arg, const struct model_rec *rec)
{
    uint8_t rbuf[REC_HDR + REC_MAX];
    size_t plen;
    (void)arg;
    if (walfd < 0)
        return -1;
    plen = encode_payload(rec, rbuf + REC_HDR);
    put64(rbuf + 8, seq + 1);
    rbuf[16] = (uint8_t)rec->op;
    put32(rbuf, (uint32_t)(plen + 9));
    put32(rbuf + 4, it2n_crc32c(rbuf + 8, plen + 9));
    if (qlen + REC_HDR + plen > qcap) {
        size_t cap = qcap ? qcap * 2 : 4096;
        uint8_t *p = realloc(qbuf, cap);
        if (!p)
            return -1;
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
    struct store_mark m = { qlen, qrecs, seq };
    return m;
}

void store_rollback(struct store_mark m)
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

int store_commit(void)
{
    int rc = 0;
    if (!qrecs)
        return 0;
    off_t before = lseek(walfd, 0, SEEK_END);
    if (write_all(walfd, qbuf, qlen) || (do_fsync && fdatasync(walfd))) {
        log_err("wal: write failed: %s; %d record(s) not acknowledged", strerror(errno), qrecs);
        /* Cut off a partial write so later records stay readable. */
        if (before >= 0 && ftruncate(walfd, before) != 0)
            log_err("wal: truncate failed: %s", strerror(errno));
        rc = -1;
    } else {
        wal_bytes += qlen;
        stats.records += (uint64_t)qrecs;
        stats.commits++;
    }
    qlen = 0;
    qrecs = 0;
    return rc;
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

/* Create an empty WAL atomically (tmp + fsync + rename). */
static int wal_reset(void)
{
    uint8_t h[WAL_HDR] = { 0 };
    int fd = openat(dirfd_, "wal.tmp", O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
    if (fd < 0)
        return -1;
    memcpy(h, WAL_MAGIC, 8);
    put32(h + 8, FORMAT_VERSION);
    if (write_all(fd, h, sizeof h) || (do_fsync && fsync(fd)) ||
        renameat(dirfd_, "wal.tmp", dirfd_, "wal") || sync_dir()) {
        close(fd);
        return -1;
    }
    close(fd);
    if (walfd >= 0)
        close(walfd);
    walfd = openat(dirfd_, "wal", O_WRONLY | O_APPEND | O_CLOEXEC);
    wal_bytes = 0;
    return walfd < 0 ? -1 : 0;
}

int store_snapshot(void)
{
    size_t size = 0;
    uint8_t *buf = NULL;
    int fd, rc = -1;
    if (store_commit())
        goto out;
    buf = snap_encode(seq, &size);
    if (!buf)
        goto out;
    fd = openat(dirfd_, "snapshot.tmp", O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
    if (fd < 0)
        goto out;
    if (write_all(fd, buf, size) || (do_fsync && fsync(fd))) {
        close(fd);
        goto out;
    }
    close(fd);
    if (renameat(dirfd_, "snapshot.tmp", dirfd_, "snapshot") || sync_dir())
        goto out;
    /* The snapshot now holds everything: start an empty WAL. A crash
     * before this leaves old records, skipped by seq on replay. */
    if (wal_reset())
        goto out;
    stats.snapshots++;
    rc = 0;
out:
    if (rc)
        log_err("snapshot failed: %s", strerror(errno));
    free(buf);
    return rc;
}

/* The snapshot is read whole; it holds at most CONF_MAX_MODELS models of
 * bounded size, far below this limit, so a larger file is not ours. */
#define SNAP_FILE_MAX ((off_t)64 << 20)

/* Read a whole file. NULL with errno ENOENT when it does not exist, EFBIG
 * over max, or the I/O error; the caller decides (and logs) what follows. */
static uint8_t *read_file(const char *name, off_t max, size_t *len)
{
    int fd = openat(dirfd_, name, O_RDONLY | O_CLOEXEC);
    struct stat st = { 0 };
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

/* Version 1: the data set of a raw record, re-put and (solve) re-solved
 * into md. On error md is unchanged. */
static int v1_rebuild(struct model *md, const struct store_v1_it2n_dataset *src, int solve,
                      it2n_errinfo *err)
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
    uint8_t *buf = read_file("snapshot", SNAP_FILE_MAX, &len);
    uint64_t sseq = 0;
    *seqp = 0;
    if (!buf) {
        if (errno == ENOENT)
            return 0;
        if (errno == EFBIG)
            log_err("snapshot: %s/snapshot is larger than the limit of %lld bytes (not a snapshot of this "
                    "daemon?); refusing to start, file left as it is",
                    state_dir, (long long)SNAP_FILE_MAX);
        else
            log_err("snapshot: cannot read %s/snapshot: %s; refusing to start, file left as it is", state_dir,
                    strerror(errno));
        return -1;
    }
    if (len < 36 || memcmp(buf, SNAP_MAGIC, 8)) {
        log_err("snapshot: not a snapshot (%zu bytes); ignored, state before the WAL is lost", len);
        goto out;
    }
    if (get32(buf + 8) == SNAP_VERSION) {
        if (snap_decode(buf, len, &sseq))
            sseq = 0;
        goto out;
    }
    if (get32(buf + 8) != FORMAT_VERSION || get32(buf + 12) != store_v1_layout_tag()) {
        log_err("snapshot: version %u / layout %08x not supported; ignored", get32(buf + 8),
                get32(buf + 12));
        goto out;
    }
    uint32_t n = get32(buf + 24);
    if (len != 32 + (size_t)n * sizeof(struct store_v1_snap_model) + 4 ||
        get32(buf + len - 4) != it2n_crc32c(buf, len - 4)) {
        log_err("snapshot: truncated or checksum mismatch (%zu bytes); ignored, state before the WAL is lost", len);
        goto out;
    }
    sseq = get64(buf + 16);
    for (uint32_t k = 0; k < n; k++) {
        struct store_v1_snap_model sm;
        it2n_errinfo err;
        memcpy(&sm, buf + 32 + (size_t)k * sizeof sm, sizeof sm);
        struct model *md = models_by_id(sm.id);
        if (!md) {
            log_warn("snapshot: model %d no longer configured; dropped", sm.id);
            continue;
        }
        /* Never trust stored derived state: rebuild the data set entry by
         * entry through the core's checks and solve it again, as version 2
         * does (the stored control nets are ignored). */
        if (sm.state < IT2N_RS_EMPTY || sm.state > IT2N_RS_FAILED ||
            v1_rebuild(md, &sm.ds, sm.state == IT2N_RS_SOLVED, &err) != IT2N_OK) {
            log_err("snapshot: model %d fails validation (%s); dropped", sm.id, it2n_strerror(err.code));
            continue;
        }
        md->state = sm.state;
        md->gen = sm.gen;
        md->points_rx = sm.points_rx;
        md->solves = sm.solves;
        memcpy(md->upload, sm.upload, sizeof md->upload);
        md->grid_valid = 0;
    }
    log_notice("snapshot: legacy version 1, %u model(s) loaded, seq %llu; the next one is written as version %u", n,
               (unsigned long long)sseq, SNAP_VERSION);
out:
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

static int replay_wal(uint64_t sseq, uint64_t *good, uint64_t *total)
{
    int fd = openat(dirfd_, "wal", O_RDONLY | O_CLOEXEC);
    struct stat st;
    uint8_t *buf = NULL;
    size_t have = 0, pos = 0;   /* bytes in buf; next record at buf[pos] */
    uint64_t base = 0;          /* file offset of buf[0] */
    unsigned long long applied = 0, skipped = 0, failed = 0;
    int eof = 0, rc = -1;
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
        uint64_t off = base + pos;
        if (off == 0) {
            if (have < WAL_HDR || memcmp(buf, WAL_MAGIC, 8) || get32(buf + 8) != FORMAT_VERSION) {
                log_err("wal: bad header (%llu bytes); whole log dropped", (unsigned long long)*total);
                stats.dropped += *total;
                rc = 0;
                goto out;
            }
            pos = WAL_HDR;
            continue;
        }
        if (have - pos < REC_HDR) {
            if (have > pos)
                log_err("wal: truncated record at offset %llu; %llu byte(s) dropped", (unsigned long long)off,
                        (unsigned long long)(*total - off));
            break;
        }
        const uint8_t *r = buf + pos;
        uint32_t rlen = get32(r);
        struct model_rec rec;
        it2n_errinfo err;
        if (rlen < 9 || rlen > 9 + REC_MAX || 8u + rlen > have - pos) {
            log_err("wal: truncated record at offset %llu; %llu byte(s) dropped", (unsigned long long)off,
                    (unsigned long long)(*total - off));
            break;
        }
        if (get32(r + 4) != it2n_crc32c(r + 8, rlen)) {
            log_err("wal: checksum mismatch at offset %llu; %llu byte(s) dropped", (unsigned long long)off,
                    (unsigned long long)(*total - off));
            break;
        }
        uint64_t rseq = get64(r + 8);
        if (decode_payload(r[16], r + REC_HDR, rlen - 9, &rec)) {
            log_err("wal: undecodable record at offset %llu; %llu byte(s) dropped", (unsigned long long)off,
                    (unsigned long long)(*total - off));
            break;
        }
        pos += 8u + rlen;
        if (rseq <= sseq) {
            skipped++;
            continue;
        }
        if (models_apply(&rec, &err) != IT2N_OK) {
            log_warn("wal: record %llu (model %d, op %d) no longer applies: %s", (unsigned long long)rseq, rec.id,
                     rec.op, it2n_strerror(err.code));
            failed++;
        } else {
            applied++;
        }
        seq = rseq;
    }
    *good = base + pos;
    log_info("wal: %llu record(s) replayed, %llu already in the snapshot, %llu failed (%llu bytes)", applied,
             skipped, failed, (unsigned long long)*good);
    stats.dropped += *total - *good;
    rc = 0;
out:
    free(buf);
    close(fd);
    return rc;
}

int store_open(const char *dir, int fsync_on)
{
    uint64_t good, total;
    do_fsync = fsync_on;
    snprintf(state_dir, sizeof state_dir, "%s", dir);
    if (mkdir(dir, 0750) && errno != EEXIST) {
        log_err("state directory %s: %s", dir, strerror(errno));
        return -1;
    }
    dirfd_ = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dirfd_ < 0) {
        log_err("state directory %s: %s", dir, strerror(errno));
        return -1;
    }
    if (load_snapshot(&seq) || replay_wal(seq, &good, &total)) {
        close(dirfd_);
        dirfd_ = -1;
        return -1;
    }
    if (good >= WAL_HDR) {
        walfd = openat(dirfd_, "wal", O_WRONLY | O_APPEND | O_CLOEXEC);
        if (walfd < 0 || (good < total && ftruncate(walfd, (off_t)good))) {
            log_err("wal: cannot reopen: %s", strerror(errno));
            return -1;
        }
        wal_bytes = good - WAL_HDR;
    } else if (wal_reset()) {
        log_err("wal: cannot create in %s: %s", dir, strerror(errno));
        return -1;
    }
    return 0;
}

int store_chown(unsigned uid, unsigned gid)
{
    static const char *const files[] = { "wal", "snapshot" };
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
    if (walfd >= 0)
        close(walfd);
    if (dirfd_ >= 0)
        close(dirfd_);
    walfd = dirfd_ = -1;
    free(qbuf);
    qbuf = NULL;
    qlen = qcap = 0;
}
