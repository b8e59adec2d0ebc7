/* links — instrument links speaking the protocol/ framing: tty devices
 * (link_serial.c) and raw USB bulk devices (link_usb.c). A link that
 * hangs up, errors or disappears is closed and reopened with exponential
 * backoff; Modbus keeps serving meanwhile. Points received update the
 * models; the ACK goes out only after the WAL commit. */
#ifndef IT2ND_LINKS_H
#define IT2ND_LINKS_H

#include <stdint.h>

#include "conf.h"

/* Open every configured link (failures retry with backoff). */
int links_start(const struct conf *c);
/* Reconcile with a reloaded configuration: unchanged links stay open. */
int links_reload(const struct conf *c);
/* Send ACKs held for the WAL commit (commit_ok 0: NACK). */
void links_release(int commit_ok);
/* The same for the ACKs waiting for WAL batches up to `batch`. */
void links_release_upto(uint64_t batch, int commit_ok);
void links_stop(void);
/* A model changed durably (after the group commit): queue one EVENT to
 * every open link. Per link only the latest EVENT per model waits when the
 * send window is full; never blocks. */
struct model;
void links_event(const struct model *md, int old_state);
/* Output counters of link k (in configuration order): frames handed to
 * the device, frames dropped whole because the output queue was full, and
 * times the tty was full (POLLOUT armed). 0, or -1 for no such link. */
struct links_out_stats {
    uint32_t frames, dropped, blocked;
};
int links_out_stats(int k, struct links_out_stats *st);
/* Links currently open (for STATUS= and tests). */
int links_up(void);
/* First retransmission timeout of a link (ms): its rto_ms key, else
 * derived from the baud rate (docs/daemon.md "Links"). */
uint32_t links_rto_ms(const struct conf_link *c);

#endif
