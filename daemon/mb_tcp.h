/* mb_tcp — Modbus TCP server on IPv4/IPv6 listeners. The daemon's loop owns
 * every socket: each connection buffers bytes non-blocking and frames
 * requests by the MBAP length field, so a slow or half-sent request from
 * one client never stalls another. Per-connection idle and byte timeouts,
 * a maximum number of clients. */
#ifndef IT2ND_MB_TCP_H
#define IT2ND_MB_TCP_H

#include "conf.h"
#include "mb_map.h"

/* Open the listeners of c. Returns 0, or -1 if none could be opened. */
int mb_tcp_start(const struct conf *c, const struct mb_map_opts *o);

/* Apply a reloaded configuration: timeouts, limits, map options take
 * effect at once; listeners are reopened only if the addresses changed
 * (live connections are kept). Returns 0 or -1. */
int mb_tcp_reload(const struct conf *c, const struct mb_map_opts *o);

/* Answer requests held for the WAL commit (commit_ok 0: exception 04). */
void mb_tcp_release(int commit_ok);
/* The same for the replies waiting for WAL batches up to `batch`. */
void mb_tcp_release_upto(uint64_t batch, int commit_ok);

/* Number of open client connections (in a slot or pending). */
int mb_tcp_clients(void);

/* Close everything. */
void mb_tcp_stop(void);

#endif
