/* mb_tcp.c — see mb_tcp.h. */
#include "mb_tcp.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <stdarg.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include "log.h"
#include "loop.h"
#include "mb_req.h"
#include "porthint.h"

/* Admission (docs/daemon.md, "Connection slots"). A connection takes one
 * of max_clients slots only with its first complete request; until then it
 * is pending and costs a descriptor and a buffer, never a slot, so idle,
 * slow or reconnecting connections cannot hold the slots. Pending
 * connections are bounded (max_pending, within RLIMIT_NOFILE): when full,
 * a new one pushes out a pending connection that has not sent a complete
 * request (the oldest of the address holding most), never one that has.
 * A complete request waits for a
 * slot at most WAIT_MS: a free one, else that of the slot holder idle
 * longest (at least evict_idle). */
#define WAIT_MS 1000
/* Descriptors kept out of the pending budget: state directory, links,
 * RTU ports, reloads. */
#define FD_RESERVE 64
/* Connections accepted per readable listener event: the rest wait for the
 * next loop iteration, so clients in their slots are served in between. */
#define ACCEPT_BATCH 256

/* Pending connections without a complete request, per client address:
 * when the pending places are full, the one pushed out comes from the
 * address holding most of them, so a flood from one address never pushes
 * out a newcomer from another while it holds more places. */
struct peer_addr {
    uint8_t a[16]; /* IPv6, IPv4 as ::ffff:a.b.c.d */
    int n;
    struct peer_addr *next;
};
#define PEER_BUCKETS 1024
static struct peer_addr *peer_tab[PEER_BUCKETS];
static int peer_max; /* an upper bound of the largest n */

struct conn {
    int fd;
    int slot;  /* 1: holds a slot (s is set up) */
    int ready; /* no slot yet, a complete request buffered */
    int ro;    /* the listener is read-only (s.read_only once in a slot) */
    struct mb_req_session s;
    uint8_t buf[MODBUS_TCP_MAX_ADU_LENGTH * 2];
    size_t len;
    uint64_t accepted;          /* ms */
    uint64_t last_rx;           /* ms, for the idle timeout */
    uint64_t last_req;          /* us, last complete request: who is idle longest */
    uint64_t ready_since;       /* ms, its first complete request (ready) */
    uint64_t partial_since;     /* ms, first byte of an incomplete request, 0 none */
    struct sockaddr_storage sa; /* peer, for the allow-list at a reload */
    struct peer_addr *pa;       /* its address' count while pending without a request */
    char laddr[80];             /* listener host:port, to find its policy at a reload */
    char peer[64];
    struct conn *next, *prev; /* accept order: oldest first */
};

static int listen_fd[CONF_MAX_LISTEN];
static struct conf_listen listen_addr[CONF_MAX_LISTEN];
static int nlisten;
static struct conn *conns, *conns_tail;
static int nconns, npending, nready; /* in a slot; without one; of those, with a request */
static int pending_cap;              /* max_pending within RLIMIT_NOFILE */
static struct mb_map_opts opts;
static int max_clients, idle_ms, byte_ms, keepalive_s, evict_ms;
static long sweep_timer, admit_timer, resume_timer;

/* Refusals (allow-list, no slot, accept errors) can come by the thousand:
 * one log line per second at most, with the count of those not logged. */
static void refusal_log(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static void refusal_log(const char *fmt, ...)
{
    static uint64_t last;
    static unsigned quiet;
    char msg[256];
    va_list ap;
    uint64_t now = loop_now_ms();
    if (last && now - last < 1000) {
        quiet++;
        return;
    }
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (quiet)
        log_notice("%s (%u more refusal(s) not logged in the last second)", msg, quiet);
    else
        log_notice("%s", msg);
    last = now;
    quiet = 0;
}

static void listen_key(const struct conf_listen *l, char *out, size_t size)
{
    snprintf(out, size, "%s%s%s:%s", strchr(l->host, ':') ? "[" : "", l->host[0] ? l->host : "*",
             strchr(l->host, ':') ? "]" : "", l->port);
}

static void admit(void);

static void on_admit_timer(void *arg)
{
    (void)arg;
    admit_timer = 0;
    admit();
}

static void schedule_admit(void)
{
    if (!admit_timer && nready)
        admit_timer = loop_add_timer(0, on_admit_timer, NULL);
}

static void addr_bytes(const struct sockaddr_storage *ss, uint8_t out[16])
{
    memset(out, 0, 16);
    if (ss->ss_family == AF_INET6) {
        memcpy(out, &((const struct sockaddr_in6 *)ss)->sin6_addr, 16);
    } else if (ss->ss_family == AF_INET) {
        out[10] = out[11] = 0xFF;
        memcpy(out + 12, &((const struct sockaddr_in *)ss)->sin_addr, 4);
    }
}

static struct peer_addr **peer_bucket(const uint8_t a[16])
{
    unsigned h = 2166136261u; /* FNV-1a */
    for (int k = 0; k < 16; k++)
        h = (h ^ a[k]) * 16777619u;
    return &peer_tab[h % PEER_BUCKETS];
}

/* c holds a pending place without a request: count it for its address. */
static int addr_hold(struct conn *c)
{
    uint8_t a[16];
    addr_bytes(&c->sa, a);
    struct peer_addr **pp = peer_bucket(a), *p;
    for (p = *pp; p && memcmp(p->a, a, 16); p = p->next)
        ;
    if (!p) {
        p = calloc(1, sizeof *p);
        if (!p)
            return -1;
        memcpy(p->a, a, 16);
        p->next = *pp;
        *pp = p;
    }
    c->pa = p;
    if (++p->n > peer_max)
        peer_max = p->n;
    return 0;
}

/* c no longer holds a place without a request (ready, or closed). */
static void addr_release(struct conn *c)
{
    struct peer_addr *p = c->pa, **pp;
    if (!p)
        return;
    c->pa = NULL;
    if (--p->n > 0)
        return;
    for (pp = peer_bucket(p->a); *pp != p; pp = &(*pp)->next)
        ;
    *pp = p->next;
    free(p);
}

static void conn_close(struct conn *c, const char *why)
{
    log_info("tcp %s: closed (%s)", c->peer, why);
    loop_del_fd(c->fd);
    if (c->s.ctx) {
        modbus_close(c->s.ctx); /* closes c->fd */
        modbus_free(c->s.ctx);
        mb_req_session_free(&c->s);
    } else {
        close(c->fd);
    }
    *(c->prev ? &c->prev->next : &conns) = c->next;
    *(c->next ? &c->next->prev : &conns_tail) = c->prev;
    addr_release(c);
    if (c->slot) {
        nconns--;
        schedule_admit(); /* a slot is free: a waiting request may take it */
    } else {
        npending--;
        nready -= c->ready;
    }
    free(c);
}

static int grant(struct conn *c, uint64_t now);

/* Frame and handle every complete request in the buffer. Stops at a held
 * request (its reply, and so any later request, waits for the commit), and
 * for a connection without a slot at its first complete request: it stops
 * reading and waits for admit(). */
static int process(struct conn *c)
{
    if (c->ready)
        return 0;
    while (c->len >= 7 && c->s.held_len == 0) {
        unsigned proto = (unsigned)c->buf[2] << 8 | c->buf[3];
        unsigned mlen = (unsigned)c->buf[4] << 8 | c->buf[5];
        if (proto != 0 || mlen < 2 || mlen > MODBUS_TCP_MAX_ADU_LENGTH - 6) {
            conn_close(c, "not Modbus TCP framing");
            return -1;
        }
        size_t total = 6 + mlen;
        if (c->len < total)
            break;
        if (!c->slot) {
            c->ready = 1;
            nready++;
            addr_release(c);
            c->ready_since = loop_now_ms();
            c->partial_since = 0;
            /* A free slot and no request waiting before it: at once. */
            if (nready == 1 && nconns < max_clients)
                return grant(c, c->ready_since);
            loop_pause_reader(c->fd, 1);
            schedule_admit();
            return 0;
        }
        c->last_req = loop_wake_us();
        if (mb_req_handle(&c->s, c->buf, (int)total, &opts) < 0) {
            conn_close(c, "send failed");
            return -1;
        }
        memmove(c->buf, c->buf + total, c->len - total);
        c->len -= total;
        /* What is left arrived with the last read: its clock starts now. */
        c->partial_since = 0;
    }
    /* The byte timeout runs while a request is incomplete and nothing holds
     * the connection (a held reply stops reading). */
    if (c->len && !c->s.held_len)
        c->partial_since = c->partial_since ? c->partial_since : loop_now_ms();
    else
        c->partial_since = 0;
    /* Stop reading while a reply is held: back-pressure, and the buffer
     * cannot overflow. */
    loop_pause_reader(c->fd, c->s.held_len != 0);
    return 0;
}

/* A chunk from the loop (daemon/loop.h, loop_add_reader): data, the end,
 * or an error (also a reply the socket could not take whole). */
static void on_data(void *arg, int fd, const uint8_t *data, ssize_t n)
{
    struct conn *c = arg;
    (void)fd;
    if (n == 0) {
        conn_close(c, "peer closed");
        return;
    }
    if (n < 0) {
        conn_close(c, n == -EAGAIN ? "send failed: the client does not read its replies" : strerror((int)-n));
        return;
    }
    /* Reading is paused while a request waits (ready) or a reply is held,
     * and every complete request is taken out before: a chunk fits. */
    if ((size_t)n > sizeof c->buf - c->len) {
        conn_close(c, "request buffer overflow");
        return;
    }
    memcpy(c->buf + c->len, data, (size_t)n);
    c->len += (size_t)n;
    c->last_rx = loop_wake_ms(); /* no clock read per request */
    process(c);
}

/* The slot holder that has gone longest without a complete request, if
 * that is at least evict_idle; never one whose reply is held. */
static struct conn *idlest(uint64_t now_us)
{
    struct conn *c, *best = NULL;
    for (c = conns; c; c = c->next)
        if (c->slot && !c->s.held_len && now_us - c->last_req >= (uint64_t)evict_ms * 1000u &&
            (!best || c->last_req < best->last_req))
            best = c;
    return best;
}

/* The connection with a complete request waiting longest for a slot. */
static struct conn *oldest_ready(void)
{
    struct conn *c, *best = NULL;
    for (c = conns; c; c = c->next)
        if (c->ready && (!best || c->ready_since < best->ready_since))
            best = c;
    return best;
}

/* Give c (ready) its slot: the Modbus session is set up only now, so a
 * pending connection costs no register map. */
static int grant(struct conn *c, uint64_t now)
{
    modbus_t *ctx = modbus_new_tcp_pi(NULL, "502");
    if (!ctx || mb_req_session_init(&c->s, ctx, 1)) {
        log_err("tcp %s: out of memory", c->peer);
        if (ctx)
            modbus_free(ctx);
        c->s.ctx = NULL;
        conn_close(c, "out of memory");
        return -1;
    }
    modbus_set_socket(ctx, c->fd);
    c->s.read_only = c->ro;
    snprintf(c->s.who, sizeof c->s.who, "tcp %s (listener %s)", c->peer, c->laddr);
    c->slot = 1;
    c->ready = 0;
    nready--;
    npending--;
    nconns++;
    log_info("tcp %s: got a slot %llu ms after its request, %llu ms after connecting (%d clients)", c->peer,
             (unsigned long long)(now - c->ready_since), (unsigned long long)(now - c->accepted), nconns);
    return process(c);
}

/* Give slots to connections with a complete request, longest waiting
 * first: a free slot, else that of the slot holder idle longest (at least
 * evict_idle). A connection without a complete request never takes a
 * slot, and never costs anyone theirs. */
static void admit(void)
{
    while (nready) {
        struct conn *w = oldest_ready();
        if (nconns >= max_clients) {
            uint64_t now_us = loop_now_us();
            struct conn *v = idlest(now_us);
            if (!v)
                return; /* every slot in active use: try again at the next sweep */
            log_notice("tcp %s: evicted after %llu ms without a request: its slot goes to %s "
                       "(all %d slots in use, max_clients)",
                       v->peer, (unsigned long long)((now_us - v->last_req) / 1000u), w->peer, max_clients);
            conn_close(v, "evicted for a new client");
        }
        grant(w, loop_now_ms());
    }
}

/* The pending connection to close when the pending places are full: the
 * oldest that has not sent a complete request, from the address holding
 * most such places; NULL when every pending connection has sent one (they
 * are never pushed out for a newcomer). */
static struct conn *pending_victim(void)
{
    for (; peer_max > 0; peer_max--)
        for (struct conn *c = conns; c; c = c->next)
            if (c->pa && c->pa->n == peer_max)
                return c;
    return NULL;
}

static void push_out(struct conn *v, const char *why)
{
    refusal_log("tcp %s: closed after %llu ms without a complete request: %s (%d pending, max_pending %d)", v->peer,
                (unsigned long long)(loop_now_ms() - v->accepted), why, npending, pending_cap);
    conn_close(v, "no request; pushed out by a newer connection");
}

static void resume_listeners(void *arg)
{
    (void)arg;
    resume_timer = 0;
    for (int k = 0; k < nlisten; k++)
        loop_mod_fd(listen_fd[k], POLLIN);
}

/* Out of descriptors or memory: the listener stays readable, so stop
 * polling it for 100 ms instead of spinning on accept(). */
static void pause_listeners(void)
{
    for (int k = 0; k < nlisten; k++)
        loop_mod_fd(listen_fd[k], 0);
    if (!resume_timer)
        resume_timer = loop_add_timer(100, resume_listeners, NULL);
}

/* Keepalive, so that a peer that vanished (a PLC that lost power) frees
 * its slot: probes after keepalive_s idle, every min(10, keepalive_s) s,
 * 3 unanswered probes close it; TCP_USER_TIMEOUT bounds unacknowledged
 * replies the same way. */
static void set_keepalive(int fd)
{
    int on = keepalive_s > 0, idle = keepalive_s, intvl = keepalive_s < 10 ? keepalive_s : 10, cnt = 3;
    unsigned ut = on ? (unsigned)(idle + intvl * cnt) * 1000u : 0;
    setsockopt(fd, SOL_SOCKET, SO_KEEPALIVE, &on, sizeof on);
    if (on) {
        setsockopt(fd, IPPROTO_TCP, TCP_KEEPIDLE, &idle, sizeof idle);
        setsockopt(fd, IPPROTO_TCP, TCP_KEEPINTVL, &intvl, sizeof intvl);
        setsockopt(fd, IPPROTO_TCP, TCP_KEEPCNT, &cnt, sizeof cnt);
    }
    setsockopt(fd, IPPROTO_TCP, TCP_USER_TIMEOUT, &ut, sizeof ut);
}

static void on_accept(void *arg, int lfd, short revents)
{
    const struct conf_listen *l = arg;
    (void)revents;
    for (int n = 0; n < ACCEPT_BATCH; n++) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        int fd = accept4(lfd, (struct sockaddr *)&ss, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        char host[48] = "?", serv[8] = "?", lk[80];
        if (fd < 0) {
            int e = errno;
            struct conn *v;
            if ((e == EMFILE || e == ENFILE) && (v = pending_victim()) != NULL) {
                /* A descriptor held by a connection that has sent no
                 * request makes room for the one waiting in the backlog. */
                push_out(v, "out of descriptors");
                continue;
            }
            if (e == EMFILE || e == ENFILE || e == ENOBUFS || e == ENOMEM) {
                refusal_log("tcp accept: %s; listeners paused for 100 ms", strerror(e));
                pause_listeners();
            } else if (e != EAGAIN && e != EINTR && e != ECONNABORTED) {
                log_warn("tcp accept: %s", strerror(e));
            }
            return;
        }
        getnameinfo((struct sockaddr *)&ss, sl, host, sizeof host, serv, sizeof serv, NI_NUMERICHOST | NI_NUMERICSERV);
        listen_key(l, lk, sizeof lk);
        if (!acl_allowed(l, (struct sockaddr *)&ss)) {
            refusal_log("tcp %s:%s: refused: not in the allow-list of listener %s%s%s", host, serv,
                        l->name[0] ? l->name : "", l->name[0] ? " " : "", lk);
            close(fd);
            continue;
        }
        /* Requests read in this batch take free slots now (admit() would
         * run after it), so that their places count as free below. */
        if (npending >= pending_cap && nready && nconns < max_clients)
            admit();
        while (npending >= pending_cap) {
            struct conn *v = pending_victim();
            if (!v)
                break;
            push_out(v, "its place goes to a new connection");
        }
        if (npending >= pending_cap) {
            /* Every pending connection has a complete request: they keep
             * their places, the newcomer is closed. */
            refusal_log("tcp %s:%s: refused: all %d pending places hold complete requests waiting for a slot "
                        "(max_pending, max_clients)",
                        host, serv, pending_cap);
            close(fd);
            continue;
        }
        struct conn *c = calloc(1, sizeof *c);
        if (!c) {
            log_err("tcp: out of memory");
            close(fd);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        set_keepalive(fd);
        c->fd = fd;
        c->accepted = c->last_rx = loop_now_ms();
        c->last_req = loop_now_us();
        c->sa = ss;
        c->ro = l->read_only;
        snprintf(c->laddr, sizeof c->laddr, "%s", lk);
        snprintf(c->peer, sizeof c->peer, "%s:%s", host, serv);
        if (loop_add_reader(fd, MODBUS_TCP_MAX_ADU_LENGTH, on_data, c)) {
            log_err("tcp: out of memory");
            close(fd);
            free(c);
            continue;
        }
        if (addr_hold(c)) {
            log_err("tcp: out of memory");
            loop_del_fd(fd);
            close(fd);
            free(c);
            continue;
        }
        c->prev = conns_tail;
        *(conns_tail ? &conns_tail->next : &conns) = c;
        conns_tail = c;
        npending++;
        log_info("tcp %s: connected (%d clients, %d pending)", c->peer, nconns, npending);
        /* A request sent right after the handshake is often here already:
         * read it now, so that the connection is ready (and can no longer
         * be pushed out) before the next connection is accepted. */
        uint8_t first[MODBUS_TCP_MAX_ADU_LENGTH];
        ssize_t r = recv(fd, first, sizeof first, 0);
        if (r >= 0 || (errno != EAGAIN && errno != EINTR))
            on_data(c, fd, first, r < 0 ? -errno : r);
    }
}

/* Every 100 ms: idle and byte (incomplete request) timeouts; a complete
 * request that got no slot within WAIT_MS is refused (closed); waiting
 * ones are admitted as slot holders become idle long enough. */
static void sweep(void *arg)
{
    uint64_t now = loop_now_ms();
    struct conn *c = conns, *next;
    (void)arg;
    for (; c; c = next) {
        next = c->next;
        if (c->partial_since && now - c->partial_since > (uint64_t)byte_ms)
            conn_close(c, "byte timeout: request incomplete");
        else if (c->ready && now - c->ready_since > WAIT_MS) {
            refusal_log("tcp %s: refused: no slot within %d ms, all %d in use by active clients (max_clients)", c->peer,
                        WAIT_MS, max_clients);
            conn_close(c, "no slot");
        } else if (!c->ready && !c->s.held_len && now - c->last_rx > (uint64_t)idle_ms)
            conn_close(c, "idle timeout");
    }
    admit();
    sweep_timer = loop_add_timer(100, sweep, NULL);
}

static int open_listener(const struct conf_listen *l)
{
    struct addrinfo hints, *res, *ai;
    int fd = -1, rc;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    rc = getaddrinfo(l->host[0] ? l->host : NULL, l->port, &hints, &res);
    if (rc) {
        log_err("tcp listen %s:%s: %s", l->host, l->port, gai_strerror(rc));
        return -1;
    }
    /* Empty host: prefer one IPv6 socket that also takes IPv4. */
    for (ai = res; ai; ai = ai->ai_next) {
        if (!l->host[0] && ai->ai_family != AF_INET6 && ai->ai_next)
            continue;
        fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
        if (fd < 0)
            continue;
        int one = 1, v6only = l->host[0] ? 1 : 0;
        setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (ai->ai_family == AF_INET6)
            setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &v6only, sizeof v6only);
        if (bind(fd, ai->ai_addr, ai->ai_addrlen) == 0 && listen(fd, 1024) == 0)
            break;
        if (errno == EADDRINUSE) {
            char hint[320];
            porthint_in_use(l->host, l->port, "it2nd --listen HOST:PORT, or tcp_listen / address in the configuration",
                            hint, sizeof hint);
            log_err("tcp listen %s:%s: %s: %s", l->host, l->port, strerror(EADDRINUSE), hint);
        } else {
            log_err("tcp listen %s:%s: %s", l->host, l->port, strerror(errno));
        }
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd >= 0) {
        char lk[80];
        listen_key(l, lk, sizeof lk);
        log_notice("modbus tcp listening on %s%s%s%s%s", lk, l->name[0] ? " (listener " : "", l->name,
                   l->name[0] ? ")" : "", l->read_only ? ", read-only" : "");
        if (l->nallow)
            log_notice("listener %s: %d allow-list entr%s", lk, l->nallow, l->nallow == 1 ? "y" : "ies");
    }
    return fd;
}

/* Pending connections need descriptors: the soft RLIMIT_NOFILE is raised
 * (up to the hard limit) to hold max_clients + max_pending + FD_RESERVE,
 * and what it cannot hold lowers the pending places (logged). */
static void fd_budget(const struct conf *c)
{
    struct rlimit rl;
    rlim_t want = (rlim_t)c->max_clients + (rlim_t)c->max_pending + FD_RESERVE;
    pending_cap = c->max_pending < 4 ? 4 : c->max_pending;
    if (getrlimit(RLIMIT_NOFILE, &rl))
        return;
    if (rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur < want) {
        struct rlimit nl = rl;
        nl.rlim_cur = rl.rlim_max != RLIM_INFINITY && rl.rlim_max < want ? rl.rlim_max : want;
        if (nl.rlim_cur > rl.rlim_cur && setrlimit(RLIMIT_NOFILE, &nl) == 0) {
            log_info("tcp: RLIMIT_NOFILE raised from %llu to %llu (max_clients + max_pending + %d)",
                     (unsigned long long)rl.rlim_cur, (unsigned long long)nl.rlim_cur, FD_RESERVE);
            rl = nl;
        }
    }
    if (rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur < want) {
        long room = (long)rl.rlim_cur - c->max_clients - FD_RESERVE;
        pending_cap = room < 4 ? 4 : (int)room;
        log_warn("tcp: RLIMIT_NOFILE %llu (hard %llu) leaves room for %d pending connections, not max_pending %d: "
                 "raise the limit (LimitNOFILE=) or lower max_pending",
                 (unsigned long long)rl.rlim_cur, (unsigned long long)rl.rlim_max, pending_cap, c->max_pending);
    }
}

static void set_opts(const struct conf *c, const struct mb_map_opts *o)
{
    opts = *o;
    max_clients = c->max_clients;
    idle_ms = c->idle_timeout * 1000;
    byte_ms = c->byte_timeout;
    keepalive_s = c->tcp_keepalive;
    evict_ms = c->evict_idle;
    fd_budget(c);
}

static void close_listeners(void)
{
    for (int k = 0; k < nlisten; k++) {
        loop_del_fd(listen_fd[k]);
        close(listen_fd[k]);
    }
    nlisten = 0;
}

static int open_listeners(const struct conf *c)
{
    int ok = 0;
    for (int k = 0; k < c->nlisten; k++) {
        int fd = open_listener(&c->listen[k]);
        if (fd < 0)
            continue;
        listen_fd[nlisten] = fd;
        listen_addr[nlisten] = c->listen[k];
        loop_add_fd(fd, POLLIN, on_accept, &listen_addr[nlisten]);
        nlisten++;
        ok++;
    }
    return (c->nlisten == 0 || ok) ? 0 : -1;
}

int mb_tcp_start(const struct conf *c, const struct mb_map_opts *o)
{
    set_opts(c, o);
    if (open_listeners(c))
        return -1;
    sweep_timer = loop_add_timer(100, sweep, NULL);
    return 0;
}

/* A reload's access policy for the live connections: each keeps the
 * policy of the listener with its address in the new configuration (a
 * listener that is gone leaves its connections as they were); one whose
 * peer that listener no longer allows is closed. */
static void recheck_conns(const struct conf *cf)
{
    struct conn *c, *next;
    for (c = conns; c; c = next) {
        next = c->next;
        set_keepalive(c->fd);
        for (int k = 0; k < cf->nlisten; k++) {
            char lk[80];
            listen_key(&cf->listen[k], lk, sizeof lk);
            if (strcmp(lk, c->laddr))
                continue;
            if (!acl_allowed(&cf->listen[k], (const struct sockaddr *)&c->sa)) {
                log_notice("tcp %s: closed: no longer in the allow-list of listener %s", c->peer, lk);
                conn_close(c, "not allowed after reload");
            } else {
                c->ro = cf->listen[k].read_only;
                c->s.read_only = c->ro;
            }
            break;
        }
    }
}

int mb_tcp_reload(const struct conf *c, const struct mb_map_opts *o)
{
    int same = c->nlisten == nlisten;
    for (int k = 0; same && k < nlisten; k++)
        same = !strcmp(c->listen[k].host, listen_addr[k].host) && !strcmp(c->listen[k].port, listen_addr[k].port);
    set_opts(c, o);
    recheck_conns(c);
    if (same) {
        /* Same sockets, new policies (the accept handlers point here). */
        for (int k = 0; k < nlisten; k++)
            listen_addr[k] = c->listen[k];
        admit();
        return 0;
    }
    log_notice("tcp: listen addresses changed; reopening listeners (connections kept)");
    close_listeners();
    admit();
    return open_listeners(c);
}

void mb_tcp_release(int commit_ok)
{
    mb_tcp_release_upto(UINT64_MAX, commit_ok);
}

void mb_tcp_release_upto(uint64_t batch, int commit_ok)
{
    struct conn *c = conns, *next;
    for (; c; c = next) {
        next = c->next;
        if (!c->s.held_len || c->s.held_batch > batch)
            continue;
        if (mb_req_release(&c->s, commit_ok) < 0) {
            conn_close(c, "send failed");
            continue;
        }
        if (process(c) == 0 && c->s.held_len)
            loop_wake();
    }
}

int mb_tcp_clients(void)
{
    return nconns + npending;
}

void mb_tcp_stop(void)
{
    while (conns)
        conn_close(conns, "shutdown");
    close_listeners();
    loop_cancel_timer(sweep_timer);
    loop_cancel_timer(admit_timer);
    loop_cancel_timer(resume_timer);
    admit_timer = resume_timer = 0;
}
