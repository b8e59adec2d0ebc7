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
#include <string.h>

#include "models.h"

/* Open (create) dir, take its lock (flock on dir/lock, held until
 * store_close; another daemon holding it: -1 before anything is read),
 * recover snapshot + WAL into the model table (models must already be
 * configured). A damaged WAL header or snapshot is renamed aside to
 * NAME.damaged-<UTC time> and -1 returned; while such a file is in dir,
 * -1 too. fsync 0 skips fdatasync (tests only). Returns 0, or -1 (logged)
 * if the directory cannot be used. */
int store_open(const char *dir, int fsync);

/* fsync on (1) or off (0) from the next WAL write or checkpoint on: the
 * [daemon] fsync key at a reload. Called with no job in progress. */
void store_set_fsync(int on);

/* Data in the state directory for a model the configuration does not
 * have (a section lost in a rewrite of the file, or removed on purpose).
 * Without a policy (unit tests, fuzzers) they are dropped with a log line.
 * With one, store_open asks it for every such model holding data points:
 * 1 = drop them (the operator said removed = yes), 0 = refuse to start,
 * files left as they are. */
typedef int (*store_drop_fn)(int id);
void store_set_drop_policy(store_drop_fn fn);

/* For the loaders (store.c, snapshot.c): may the data of unconfigured
 * model id (points of them, 0 if not counted, found in file) be dropped?
 * Logs the refusal. */
int store_may_drop(int id, unsigned points, const char *file);

/* Damage inside the WAL (a record that does not validate, or a hole in the
 * sequence, with valid records behind it): store_open refuses to start and
 * leaves the file as it is, since acknowledged records would be lost. A
 * damaged last record with nothing valid behind it is a torn tail (a
 * commit cut short by a crash, never acknowledged): cut off silently. With
 * on = 1 (it2nd --accept-wal-loss, the operator's explicit act) the next
 * store_open cuts at the damage instead, keeping the bytes cut off in
 * wal.cut-<UTC time>, and logs what was given up. */
void store_accept_wal_loss(int on);

/* Queue one record (model journal hook). Returns 0, or IT2ND_ERR_DEGRADED,
 * IT2ND_ERR_IO or IT2ND_ERR_NOMEM (errs.h): the change is refused. */
int store_append(void *arg, const struct model_rec *rec);

/* Write and fdatasync queued records, synchronously (waits for the job in
 * flight first). Returns 0, or -1 (the queued records are then lost and
 * must not be acknowledged; the store is degraded). */
int store_commit(void);

/* The writer thread (docs/daemon.md, "The writer thread"): the WAL
 * appends, fdatasyncs and checkpoints run on it, one job at a time, so
 * the serving loop never waits for the disk. Without it (unit tests) jobs
 * run inline in the submitting call.
 *
 * store_start_writer: start the thread; returns an eventfd, readable when
 * a job is done (register it in the loop and call store_reap), or -1.
 * store_submit: hand every record queued since the last submit to the
 * writer as one job (group commit: one write + one fdatasync). Returns 1
 * (submitted; *batch = its id), 0 (nothing queued, or a job in flight:
 * the records wait for the next submit), -1 (store degraded: the queued
 * records are dropped, nothing may be acknowledged).
 * store_batch: the id the records queued now will have when submitted
 * (held replies are tagged with it and released when it is reaped).
 * store_submit_checkpoint: a checkpoint job (snapshot of the durable
 * state, i.e. of models_view() of every model, at the last durable seq,
 * then a new WAL); 1, 0 (busy) or -1 (logged).
 * store_reap: the job done, if any (1; *d filled), else 0. Applies its
 * result to the store (durable seq, degraded state, logs).
 * store_wait: block until the job in flight is done (synchronous paths:
 * reload, shutdown). */
struct store_done {
    int kind; /* STORE_DONE_COMMIT or STORE_DONE_CHECKPOINT */
    int ok;
    uint64_t batch; /* commit: the batch id */
    uint64_t us;    /* how long the job's I/O took */
};
enum { STORE_DONE_COMMIT = 1, STORE_DONE_CHECKPOINT = 2 };
int store_start_writer(void);
int store_submit(uint64_t *batch);
uint64_t store_batch(void);
int store_submit_checkpoint(void);
int store_reap(struct store_done *d);
int store_busy(void);
void store_wait(void);

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
/* The same for models.c transactions (models_set_journal_marks). */
struct model_jmark store_jmark(void);
void store_jrewind(struct model_jmark m);

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

/* Legacy version 1 snapshot (it2nd 0.1, read only): a raw dump of
 * struct store_v1_snap_model per model, tagged with store_v1_layout_tag().
 * The model inside is the core v1 it2n_model, frozen here (the core's own
 * type has changed since), so such files keep loading after an upgrade.
 * Only ds is used; the stored control nets are ignored (solved again).
 * The core v1 data set layout, frozen likewise: */
struct store_v1_it2n_dataset {
    uint8_t n, m;
    uint8_t flags;
    uint8_t present[IT2N_DIM][IT2N_DIM];
    it2n_val values[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT][IT2N_CH_COUNT];
};

struct store_v1_it2n_model {
    struct store_v1_it2n_dataset data;
    it2n_par u[IT2N_DIM], w[IT2N_DIM];
    it2n_par ainv[IT2N_DIM][IT2N_DIM];
    it2n_par binv[IT2N_DIM][IT2N_DIM];
    it2n_val ctrl[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT][IT2N_CH_COUNT];
    int32_t ctrl_rem[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT][IT2N_CH_COUNT];
    uint32_t generation;
    uint8_t solved;
};

struct store_v1_snap_model {
    int32_t id, state;
    uint32_t gen, points_rx, solves;
    uint16_t upload[IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I];
    struct store_v1_it2n_dataset ds;
    struct store_v1_it2n_model mdl;
};

/* A data set in the frozen v1 layout (tests write legacy snapshots). */
static inline void store_v1_dataset_from(struct store_v1_it2n_dataset *d, const it2n_dataset *ds)
{
    memset(d, 0, sizeof *d);
    d->n = ds->n;
    d->m = ds->m;
    d->flags = ds->flags;
    memcpy(d->present, ds->present, sizeof d->present);
    for (unsigned i = 0; i < IT2N_DIM; i++)
        for (unsigned j = 0; j < IT2N_DIM; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
                it2n_dataset_get(ds, i, j, fp, d->values[i][j][fp]);
}

static inline uint32_t store_v1_layout_tag(void)
{
    return (uint32_t)(sizeof(struct store_v1_it2n_dataset) ^ (sizeof(struct store_v1_it2n_model) << 12)) ^
           (uint32_t)IT2N_MAX_DEGREE << 28;
}

#endif
