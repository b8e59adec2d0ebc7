/* link_serial — open a tty (or /dev/serial/by-id/... link, or pty) raw at a
 * configured baud rate, non-blocking, for an instrument link. */
#ifndef IT2ND_LINK_SERIAL_H
#define IT2ND_LINK_SERIAL_H

/* Returns the fd, or -1 with errno set (EBUSY: another process holds the
 * device, see link_serial_lock). */
int link_serial_open(const char *device, int baud);

/* One owner per serial device: an exclusive, non-blocking flock on fd (the
 * convention of picocom and minicom). 0, or -1 with errno EBUSY when
 * another process holds it (or another flock error). */
int link_serial_lock(int fd);

/* What the logs say of a device link_serial_lock refused. */
#define LINK_SERIAL_LOCKED "device locked by another process (another it2nd, or a terminal program holding it)"

#endif
