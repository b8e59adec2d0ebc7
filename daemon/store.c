/* store.c — see store.h.
 *
 * WAL file "wal":  header "IT2NWAL\0" u32 version(1) u32 0, then records
 *   u32 len (of seq..payload), u32 crc32c (of seq..payload), u64 seq,
 *   u8 type, payload. All little-endian.
 * Snapshot "snapshot": version 2 is the portable format of snapshot.c.
 *   Version 1 (raw struct dump tagged with the struct layout, written by
 *   it2nd 0.1) is still read when the layout matches this build, so an
 *   upgrade keeps its state; it is never written.
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

static void put32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; k++)
        p[k] = (uint8_t)(v >> (8 * k));
}

static void put64(uint8_t *p, uint64_t v)
{
    for (int k = 0; k < 8; k++)
        p[k] = (uint8_t)(v >> (8 * k));
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get64(const uint8_t *p)
{
    return (uint64_t)get32(p) | (uint64_t)get32(p + 4) << 32;
}

static uint32_t layout_tag(void)
{
    return (uint32_t)(sizeof(it2n_dataset) ^ (sizeof(it2n_model) << 12)) ^ (uint32_t)IT2N_MAX_DEGREE << 28;
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

struct snap_model {
    int32_t id, state;
    uint32_t gen, points_rx, solves;
    uint16_t upload[IT2N_REG_UPLOAD_END - IT2N_REG_UP_I];
    it2n_dataset ds;
    it2n_model mdl;
};

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

static uint8_t *read_file(const char *name, size_t *len)
{
    int fd = openat(dirfd_, name, O_RDONLY | O_CLOEXEC);
    struct stat st;
    uint8_t *buf;
    if (fd < 0)
        return NULL;
    if (fstat(fd, &st) || st.st_size > (off_t)64 << 20) {
        close(fd);
        return NULL;
    }
    buf = malloc((size_t)st.st_size + 1);
    if (buf && read(fd, buf, (size_t)st.st_size) != st.st_size) {
        free(buf);
        buf = NULL;
    }
    close(fd);
    *len = (size_t)st.st_size;
    return buf;
}

/* Version 1: the data set of a raw record, re-put and (solve) re-solved
 * into md. On error md is unchanged. */
static int v1_rebuild(struct model *md, const it2n_dataset *src, int solve, it2n_errinfo *err)
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

/* Load the snapshot into the models. Returns the seq it covers (0 none). */
static uint64_t load_snapshot(void)
{
    size_t len = 0;
    uint8_t *buf = read_file("snapshot", &len);
    uint64_t sseq = 0;
    if (!buf) {
        if (errno != ENOENT)
            log_err("snapshot: cannot read: %s", strerror(errno));
        return 0;
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
    if (get32(buf + 8) != FORMAT_VERSION || get32(buf + 12) != layout_tag()) {
        log_err("snapshot: version %u / layout %08x not supported; ignored", get32(buf + 8),
                get32(buf + 12));
        goto out;
    }
    uint32_t n = get32(buf + 24);
    if (len != 32 + (size_t)n * sizeof(struct snap_model) + 4 ||
        get32(buf + len - 4) != it2n_crc32c(buf, len - 4)) {
        log_err("snapshot: truncated or checksum mismatch (%zu bytes); ignored, state before the WAL is lost", len);
        goto out;
    }
    sseq = get64(buf + 16);
    for (uint32_t k = 0; k < n; k++) {
        struct snap_model sm;
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
    return sseq;
}

/* Replay the WAL after sseq; returns the valid length of the file. */
static size_t replay_wal(uint64_t sseq, size_t *total)
{
    size_t len = 0, off = WAL_HDR;
    uint8_t *buf = read_file("wal", &len);
    unsigned applied = 0, skipped = 0, failed = 0;
    *total = len;
    if (!buf)
        return 0;
    if (len < WAL_HDR || memcmp(buf, WAL_MAGIC, 8) || get32(buf + 8) != FORMAT_VERSION) {
        log_err("wal: bad header (%zu bytes); whole log dropped", len);
        free(buf);
        stats.dropped += len;
        return 0;
    }
    seq = sseq;
    while (off + REC_HDR <= len) {
        uint32_t rlen = get32(buf + off);
        struct model_rec rec;
        it2n_errinfo err;
        if (rlen < 9 || rlen > 9 + REC_MAX || off + 8 + rlen > len) {
            log_err("wal: truncated record at offset %zu; %zu byte(s) dropped", off, len - off);
            break;
        }
        if (get32(buf + off + 4) != it2n_crc32c(buf + off + 8, rlen)) {
            log_err("wal: checksum mismatch at offset %zu; %zu byte(s) dropped", off, len - off);
            break;
        }
        uint64_t rseq = get64(buf + off + 8);
        if (decode_payload(buf[off + 16], buf + off + REC_HDR, rlen - 9, &rec)) {
            log_err("wal: undecodable record at offset %zu; %zu byte(s) dropped", off, len - off);
            break;
        }
        off += 8 + rlen;
        if (rseq <= sseq) {
            skipped++;
            continue;
        }
        if (models_apply(&rec, &err) != IT2N_OK) {
            log_warn("wal: record %llu (model %d, op %d) no longer applies: %s",
                     (unsigned long long)rseq, rec.id, rec.op, it2n_strerror(err.code));
            failed++;
        } else {
            applied++;
        }
        seq = rseq;
    }
    if (off < len && off + REC_HDR > len)
        log_err("wal: truncated record at offset %zu; %zu byte(s) dropped", off, len - off);
    log_info("wal: %u record(s) replayed, %u already in the snapshot, %u failed", applied, skipped, failed);
    stats.dropped += len - off;
    free(buf);
    return off;
}

int store_open(const char *dir, int fsync_on)
{
    size_t good, total = 0;
    do_fsync = fsync_on;
    if (mkdir(dir, 0750) && errno != EEXIST) {
        log_err("state directory %s: %s", dir, strerror(errno));
        return -1;
    }
    dirfd_ = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dirfd_ < 0) {
        log_err("state directory %s: %s", dir, strerror(errno));
        return -1;
    }
    seq = load_snapshot();
    good = replay_wal(seq, &total);
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
