/* metrics — the Prometheus endpoint: [metrics] listen = HOST:PORT (or
 * it2nd --metrics) serves GET /metrics in the text exposition format
 * 0.0.4 (libmicrohttpd); any other path is 404. Off by default.
 *
 * Threads: none of its own. libmicrohttpd runs in "external event loop"
 * mode on an epoll fd that the daemon's event loop watches, and every
 * request is parsed, rendered and sent from the loop, non-blocking. So the
 * exposition reads models, connections, links and the store in the thread
 * that owns them, with no locks and no copies; a slow or stuck HTTP client
 * costs one connection slot (CONNECTION_LIMIT) until its timeout and never
 * a wait. The one value written by another thread, the WAL fsync
 * histogram (the writer thread, store.c), is kept under a mutex held only
 * to add or read a sample, never during I/O. docs/daemon.md "Metrics". */
#ifndef IT2ND_METRICS_H
#define IT2ND_METRICS_H

#include <stdint.h>

#include "conf.h"

/* Open the endpoint of c->metrics (nothing when off). c is read again at
 * each scrape (link names): it must stay valid until metrics_stop.
 * Returns 0, or -1 (logged: the address cannot be bound). */
int metrics_start(const struct conf *c);
void metrics_stop(void);
/* The address the endpoint listens on ("" when off). */
const char *metrics_address(void);

/* A Modbus reply went out (loop thread): request function fc (the byte of
 * the request) and exception code exc (0: a normal reply). */
void metrics_modbus_reply(int fc, int exc);

/* One WAL fsync/fdatasync (any thread): how long it took, whether it
 * succeeded. */
void metrics_wal_fsync(uint64_t us, int ok);

/* Render the whole exposition into a heap buffer (*len bytes, caller
 * frees), for the endpoint and the unit tests; NULL when out of memory. */
char *metrics_render(const struct conf *c, size_t *len);

#endif
