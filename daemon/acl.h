/* acl — allow-lists of TCP listeners: IPv4 and IPv6 addresses and
 * prefixes, parsed from the configuration ([listen:NAME] allow) and
 * matched against a client's address at accept. */
#ifndef IT2ND_ACL_H
#define IT2ND_ACL_H

#include <stddef.h>
#include <stdint.h>

/* An address or prefix: family 4 or 6, the first `bits` bits of addr
 * (network byte order; IPv4 in addr[0..3]). */
struct acl_prefix {
    uint8_t family;
    uint8_t bits;
    uint8_t addr[16];
};

struct conf_listen;
struct sockaddr;

/* Parse one allow-list entry: a numeric IPv4 or IPv6 address ([v6] too),
 * optionally /bits; host bits beyond the prefix must be 0. Returns 0, or
 * -1 with the reason in why. */
int acl_parse_prefix(const char *s, struct acl_prefix *p, char *why, size_t size);

/* Is the client address (AF_INET or AF_INET6; an IPv4-mapped IPv6 address
 * counts as IPv4) allowed by listener l? No allow entries: everyone. */
int acl_allowed(const struct conf_listen *l, const struct sockaddr *sa);

#endif
