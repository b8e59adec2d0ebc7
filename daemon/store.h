/* store — persistence in the state directory: a write-ahead log of model
 * records (CRC-32C protected, versioned) with group commit, and periodic
 * snapshots of every model written to a temporary file, fsynced and
 * renamed into place.
 *
 * Contract: store_append() queues a record; nothing may be acknowledged
 * until store_commit() has returned 0 (one write + fdatasync for every
 * record queued since the last commit). Recovery keeps every record that
 * validates, logs what it drops and truncates the WAL after the last good
 * record. */
#ifndef IT2ND_STORE_H
#define IT2ND_STORE_H

#include <stddef.h>
#include <stdint.h>

#include "models.h"

/* Open (create) dir, take its lock (flock on dir/lock, held until
 * store_close; another daemon holding it: -1 before anything is read),
 * recover snapshot + WAL into the model table (models must already be
 * configured). A damaged WAL header or snapshot is renamed aside to
 * NAME.damaged-<UTC time> and -1 returned; while such a file is in dir,
 * -1 too. fsync 0 skips fdatasync (tests only). Returns 0, or -1 (logged)
 * if the directory cannot be used. */
int store_open(const char *dir, int fsync);

/* Queue one record (model journal hook). Returns 0, or IT2ND_ERR_DEGRADED,
 * IT2ND_ERR_IO or IT2ND_ERR_NOMEM (errs.h): the change is refused. */
int store_append(void *arg, const struct model_rec *rec);

/* Write and fdatasync queued records. Returns 0, or -1 (the queued
 * records are then lost and must not be acknowledged; the store is
 * degraded). */
int store_commit(void);

/* True after an I/O error left the WAL not provably durable: every write
 * is refused until store_snapshot() (a checkpoint) succeeds. */
int store_degraded(void);

/* Records queued and not yet committed. */
int store_pending(void);

/* Drop records queued after a mark (a batch that failed half-way). */
struct store_mark {
    size_t len;
    int recs;
    uint64_t seq;
};
struct store_mark store_mark(void);
void store_rollback(struct store_mark m);

/* Write a snapshot of all models, then start an empty WAL (a checkpoint;
 * clears the degraded state). 0 or -1 (logged; no temporary file left,
 * the state on disk still durable). */
int store_snapshot(void);

/* Bytes in the WAL since the last snapshot. */
uint64_t store_wal_bytes(void);

/* Counters for STATUS=. */
struct store_stats {
    uint64_t records, commits, snapshots, dropped;
};
void store_get_stats(struct store_stats *st);

/* Give the state directory and its files to uid:gid (before dropping
 * root). Returns 0 or -1 (errno set). */
int store_chown(unsigned uid, unsigned gid);

void store_close(void);

#endif
