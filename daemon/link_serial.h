/* link_serial — open a tty (or /dev/serial/by-id/... link, or pty) raw at a
 * configured baud rate, non-blocking, for an instrument link. */
#ifndef IT2ND_LINK_SERIAL_H
#define IT2ND_LINK_SERIAL_H

/* Returns the fd, or -1 with errno set. */
int link_serial_open(const char *device, int baud);

#endif
