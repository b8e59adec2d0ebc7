/* acl.c — see acl.h. */
#include "acl.h"
#include "conf.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

static int parse_bits(const char *v, int max, int *out)
{
    char *end;
    long x = strtol(v, &end, 10);
    if (!*v || *end || x < 0 || x > max)
        return -1;
    *out = (int)x;
    return 0;
}

int acl_parse_prefix(const char *s, struct acl_prefix *p, char *why, size_t size)
{
    char buf[64];
    const char *slash = strchr(s, '/');
    size_t alen = slash ? (size_t)(slash - s) : strlen(s);
    int bits, max;
    memset(p, 0, sizeof *p);
    if (alen >= sizeof buf || alen == 0) {
        snprintf(why, size, "'%s': expected an IPv4 or IPv6 address, optionally /prefix", s);
        return -1;
    }
    memcpy(buf, s, alen);
    buf[alen] = 0;
    if (buf[0] == '[' && buf[alen - 1] == ']') { /* [v6] */
        memmove(buf, buf + 1, alen - 2);
        buf[alen - 2] = 0;
    }
    if (inet_pton(AF_INET, buf, p->addr) == 1) {
        p->family = 4;
        max = 32;
    } else if (inet_pton(AF_INET6, buf, p->addr) == 1) {
        p->family = 6;
        max = 128;
    } else {
        snprintf(why, size, "'%s': not a numeric IPv4 or IPv6 address (host names are not looked up)", buf);
        return -1;
    }
    bits = max;
    if (slash && parse_bits(slash + 1, max, &bits)) {
        snprintf(why, size, "'%s': prefix length must be 0..%d", s, max);
        return -1;
    }
    p->bits = (uint8_t)bits;
    for (int k = bits; k < max; k++)
        if (p->addr[k / 8] & (0x80u >> (k % 8))) {
            snprintf(why, size, "'%s': host bits set beyond /%d", s, bits);
            return -1;
        }
    return 0;
}

int acl_allowed(const struct conf_listen *l, const struct sockaddr *sa)
{
    uint8_t a[16];
    int fam;
    if (l->nallow == 0)
        return 1;
    if (sa->sa_family == AF_INET) {
        memcpy(a, &((const struct sockaddr_in *)(const void *)sa)->sin_addr, 4);
        fam = 4;
    } else if (sa->sa_family == AF_INET6) {
        const struct in6_addr *v6 = &((const struct sockaddr_in6 *)(const void *)sa)->sin6_addr;
        if (IN6_IS_ADDR_V4MAPPED(v6)) {
            memcpy(a, v6->s6_addr + 12, 4);
            fam = 4;
        } else {
            memcpy(a, v6->s6_addr, 16);
            fam = 6;
        }
    } else {
        return 0;
    }
    for (int k = 0; k < l->nallow; k++) {
        const struct acl_prefix *p = &l->allow[k];
        int b = p->bits, full = b / 8, rest = b % 8;
        if (p->family != fam || memcmp(a, p->addr, (size_t)full))
            continue;
        if (rest && ((a[full] ^ p->addr[full]) & (0xFFu << (8 - rest)) & 0xFFu))
            continue;
        return 1;
    }
    return 0;
}
