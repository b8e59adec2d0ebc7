/* spb_sf — store-and-forward for the Sparkplug edge node (docs/sparkplug.md,
 * "Primary host and store-and-forward"): while the primary host or the
 * broker is away, every change of a device (the metrics that moved, with
 * the time they moved) is appended to sparkplug.sf in state_dir and made
 * durable (fdatasync) before the node goes on, so a restart keeps it too;
 * when the host is back the node reads the records in order and publishes
 * them as historical DDATA, then clears the file. At most max records are
 * kept: a change beyond that is refused (counted by the caller, logged).
 *
 * Record: u32 len, u32 crc32c of the body, body = u16 device id, u64 ms,
 * u16 count, count x (u16 metric index, u8 null, u32 float bits, u64
 * integer), little-endian. A torn or corrupt tail (a power cut during an
 * append) is cut off at open, with a warning. One file per daemon. */
#ifndef IT2ND_SPB_SF_H
#define IT2ND_SPB_SF_H

#include <stddef.h>
#include <stdint.h>

#include "spb_payload.h"

#define SPB_SF_FILE "sparkplug.sf"

/* One stored change: values[k] is metric idx[k] of device dev. */
struct spb_sf_rec {
    int dev;
    uint64_t ts;
    int n;
    uint16_t *idx;
    struct spb_payload_val *val;
};

/* Open (create) state_dir/sparkplug.sf with room for max records; reads
 * what a previous run kept. Returns the records kept (>= 0) or -1 (I/O
 * error, logged). */
int spb_sf_open(const char *state_dir, int max);

/* Records kept now. */
int spb_sf_count(void);

/* Append a change of device dev at ts (n metrics, their indexes and
 * values), durably. Returns 0, 1 when the store is full (nothing
 * written), -1 on an I/O error (logged; nothing kept). */
int spb_sf_append(int dev, uint64_t ts, int n, const uint16_t *idx, const struct spb_payload_val *val);

/* Read the record at *off (start at 0) into rec (caller frees rec->idx,
 * rec->val with spb_sf_rec_free) and advance *off. Returns 1 with a
 * record, 0 at the end, -1 on an I/O error. */
int spb_sf_read(uint64_t *off, struct spb_sf_rec *rec);
void spb_sf_rec_free(struct spb_sf_rec *rec);

/* Every record has been delivered: empty the file, durably. 0 or -1. */
int spb_sf_clear(void);

void spb_sf_close(void);

#endif
