/* snapshot — the portable snapshot format (versions 2, 3 and 4): every
 * model's configuration, state, counters and the data points present,
 * values as little-endian int64 Q24 (version 4: memberships in Q30),
 * CRC-32C protected. The control nets are derived
 * state and are re-solved on load, so a snapshot written by a build with
 * another IT2N_MAX_DEGREE (or another struct layout) loads as long as its
 * models fit. The byte layout is documented in docs/daemon.md. */
#ifndef IT2ND_SNAPSHOT_H
#define IT2ND_SNAPSHOT_H

#include <stddef.h>
#include <stdint.h>

#define SNAPSHOT_MAGIC "IT2NSNP"   /* 8 bytes with the NUL */
#define SNAPSHOT_VERSION_FINE 4u   /* written when a membership is not Q24-exact */
#define SNAPSHOT_VERSION 3u        /* else when a model is of the B-spline kind */
#define SNAPSHOT_VERSION_BEZIER 2u /* written otherwise (older builds read it) */
#define SNAPSHOT_HDR 32u

/* Encode every model of the table, covering the WAL up to seq. Returns a
 * malloc'd buffer (caller frees) and its length, or NULL (no memory). */
uint8_t *snapshot_encode(uint64_t seq, size_t *len, int durable_view);

/* The largest snapshot nmodels Bezier models can give (every grid point
 * of the largest degree with every footprint), and what the B-spline
 * models of the table add at most (their configured grids): the room a
 * checkpoint needs. */
size_t snapshot_max_size(int nmodels);
size_t snapshot_max_size_bspline(void);

/* snapshot_decode results. */
#define SNAPSHOT_BAD (-1)       /* length, CRC-32C or structure: the file is damaged */
#define SNAPSHOT_BAD_MODEL (-2) /* a model record does not validate: damaged too     */
#define SNAPSHOT_NOMEM (-3)
#define SNAPSHOT_UNCONFIGURED (-4) /* data of a model not configured, not to be dropped */

/* Decode a version 2 or 3 file into the model table. The whole file is checked
 * first (length, CRC-32C, structure): on failure SNAPSHOT_BAD and nothing
 * changed. Then each model is rebuilt and re-solved on its own; one that is
 * no longer configured (and holds no data points, or store_may_drop()
 * allows it; else SNAPSHOT_UNCONFIGURED) or beyond this build's IT2N_MAX_DEGREE is dropped
 * with a log line (a configuration choice); one that does not validate
 * gives SNAPSHOT_BAD_MODEL (the caller refuses to start, so what was loaded
 * before it does not matter). Returns 0 and the covered WAL seq. */
int snapshot_decode(const uint8_t *buf, size_t len, uint64_t *seq);

#endif
