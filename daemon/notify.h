/* notify — the sd_notify protocol written by hand over $NOTIFY_SOCKET (a
 * datagram AF_UNIX socket, abstract when it starts with '@'), so the daemon
 * needs no libsystemd. Without NOTIFY_SOCKET every call is a no-op. */
#ifndef IT2ND_NOTIFY_H
#define IT2ND_NOTIFY_H

#include <stdint.h>

/* Read NOTIFY_SOCKET and WATCHDOG_USEC. Returns 0, or -1 when the socket
 * address is unusable (logged; notifications then disabled). */
int notify_init(void);

/* Send one state string ("READY=1\nSTATUS=..."). Returns 0 or -1. */
int notify_send(const char *state);

/* Watchdog interval the service manager asked for, in ms (0 = none). */
uint64_t notify_watchdog_ms(void);

#endif
