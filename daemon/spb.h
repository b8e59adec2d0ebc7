/* spb — it2nd as a Sparkplug B 3.0 Edge Node on MQTT 3.1.1 (libmosquitto),
 * each model a Device "model-N" (docs/sparkplug.md). The MQTT client runs
 * inside the daemon's event loop: its socket is a loop fd, its keep-alive
 * a loop timer, and every call is non-blocking (no thread, no lock; the
 * one wait is the bounded NDEATH hand-off at a graceful stop). Nothing
 * here runs unless the configuration has a [sparkplug] section. */
#ifndef IT2ND_SPB_H
#define IT2ND_SPB_H

#include "conf.h"

/* Start the edge node when c has [sparkplug]: the first connection
 * attempt is made from the loop at once. Call after the models are
 * restored (the births carry them). version: the daemon's, for the
 * NBIRTH. Returns 0 (also when not configured) or -1 (cannot start:
 * logged). */
int spb_start(const struct conf *c, const char *version);

/* Model id changed durably (or its status otherwise): a DDATA with what
 * changed goes out at the end of this loop pass when the node is online. */
void spb_model_changed(int id);

/* A group commit ended: whatever it made durable (a data point that
 * moved neither state nor generation too) goes out as DDATA at the end of
 * this loop pass; devices whose metrics did not move send nothing. */
void spb_batch_done(void);

/* The configuration was reloaded (models added/removed, grid size):
 * DDEATH for devices that went, a new birth sequence when the metric set
 * changed. [sparkplug] changes take effect at restart (logged). */
void spb_reload(const struct conf *c);

/* Graceful stop: pending DDATA (output flushed for at most 1 s), then
 * NDEATH (QoS 1, its PUBACK waited for at most 2 s), then DISCONNECT, so
 * the broker does not send the will as well. */
void spb_stop(void);

#endif
