/* porthint — what holds a TCP port, for "address already in use" errors:
 * the listening socket in /proc/net/tcp{,6} and the process whose fd is
 * that socket (visible for the same user, or any as root). */
#ifndef IT2ND_PORTHINT_H
#define IT2ND_PORTHINT_H

#include <stddef.h>

/* Write into buf what listens on TCP port (e.g. "it2nd (pid 951)", or
 * "another process (not visible to this user)"); "" when nothing is
 * found listening. Reads /proc only; bounded by the process count. */
void porthint_holder(int port, char *buf, size_t size);

/* The hint appended to a bind error on host:port: what holds it and what
 * to do ("... is held by X; stop it or choose another port (FLAG or
 * KEY)"). what_flag names the flag and key that set the address. */
void porthint_in_use(const char *host, const char *port, const char *what_flag, char *buf, size_t size);

#endif
