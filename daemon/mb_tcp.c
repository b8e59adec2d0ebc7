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
#include <sys/socket.h>
#include <unistd.h>

#include "log.h"
#include "loop.h"
#include "mb_req.h"
#include "porthint.h"

/* At most this many new connections wait for a slot when all max_clients
 * slots are in use, each for at most WAIT_MS; more push out the oldest. */
#define WAIT_MAX 16
#define WAIT_MS 1000

struct conn {
    int fd;
    struct mb_session s;
    uint8_t buf[MODBUS_TCP_MAX_ADU_LENGTH * 2];
    size_t len;
    uint64_t accepted;      /* ms */
    uint64_t last_rx;       /* ms, for the idle timeout */
    uint64_t last_req;      /* us, last complete request (or accept): who is idle longest */
    uint64_t partial_since; /* ms, first byte of an incomplete request, 0 none */
    int waiting;            /* 1: no slot yet (all max_clients in use) */
    struct sockaddr_storage sa; /* peer, for the allow-list at a reload */
    char laddr[80];         /* listener host:port, to find its policy at a reload */
    char peer[64];
    struct conn *next;
};

static int listen_fd[CONF_MAX_LISTEN];
static struct conf_listen listen_addr[CONF_MAX_LISTEN];
static int nlisten;
static struct conn *conns;
static int nconns, nwait;   /* connections holding a slot, waiting for one */
static struct mb_opts opts;
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
    if (!admit_timer && nwait)
        admit_timer = loop_add_timer(0, on_admit_timer, NULL);
}

static void conn_close(struct conn *c, const char *why)
{
    struct conn **pp;
    log_info("tcp %s: closed (%s)", c->peer, why);
    loop_del_fd(c->fd);
    modbus_close(c->s.ctx); /* closes c->fd */
    modbus_free(c->s.ctx);
    mb_session_free(&c->s);
    for (pp = &conns; *pp; pp = &(*pp)->next)
        if (*pp == c) {
            *pp = c->next;
            break;
        }
    if (c->waiting) {
        nwait--;
    } else {
        nconns--;
        schedule_admit(); /* a slot is free: a waiting client may take it */
    }
    free(c);
}

/* A complete request is in the buffer (framing already checked). */
static int has_request(const struct conn *c)
{
    return c->len >= 7 && c->len >= 6u + ((unsigned)c->buf[4] << 8 | c->buf[5]);
}

/* Frame and handle every complete request in the buffer. Stops at a held
 * request (its reply, and so any later request, waits for the commit), and
 * for a connection still waiting for a slot at its first complete request
 * (admit() gives it one). */
static int process(struct conn *c)
{
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
        if (c->waiting) {
            c->partial_since = 0;
            loop_mod_fd(c->fd, 0);
            schedule_admit();
            return 0;
        }
        c->last_req = loop_now_us();
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
    loop_mod_fd(c->fd, c->s.held_len ? 0 : POLLIN);
    return 0;
}

static void on_conn(void *arg, int fd, short revents)
{
    struct conn *c = arg;
    ssize_t r;
    if (revents & (POLLERR | POLLNVAL)) {
        conn_close(c, "socket error");
        return;
    }
    r = recv(fd, c->buf + c->len, sizeof c->buf - c->len, 0);
    if (r == 0) {
        conn_close(c, "peer closed");
        return;
    }
    if (r < 0) {
        if (errno != EAGAIN && errno != EINTR)
            conn_close(c, strerror(errno));
        return;
    }
    c->len += (size_t)r;
    c->last_rx = loop_now_ms();
    process(c);
}

/* The established connection that has gone longest without a complete
 * request, if that is at least evict_idle; never one whose reply is held. */
static struct conn *idlest(uint64_t now_us)
{
    struct conn *c, *best = NULL;
    for (c = conns; c; c = c->next)
        if (!c->waiting && !c->s.held_len && now_us - c->last_req >= (uint64_t)evict_ms * 1000u &&
            (!best || c->last_req < best->last_req))
            best = c;
    return best;
}

/* Give slots to waiting connections, oldest first: a free slot to the
 * oldest; when none is free, the slot of the connection idle longest (at
 * least evict_idle) to the oldest that has sent a complete request. A
 * newcomer must send a request before it can take anyone's slot, so
 * connection attempts alone never disturb a client. */
static void admit(void)
{
    while (nwait) {
        uint64_t now = loop_now_ms();
        int free_slot = nconns < max_clients;
        struct conn *c, *w = NULL;
        for (c = conns; c; c = c->next)
            if (c->waiting && (free_slot || has_request(c)) && (!w || c->accepted < w->accepted))
                w = c;
        if (!w)
            return;
        if (!free_slot) {
            uint64_t now_us = loop_now_us();
            struct conn *v = idlest(now_us);
            if (!v)
                return; /* every slot in active use: try again at the next sweep */
            log_notice("tcp %s: evicted after %llu ms without a request: its slot goes to %s "
                       "(all %d slots in use, max_clients)", v->peer,
                       (unsigned long long)((now_us - v->last_req) / 1000u), w->peer, max_clients);
            conn_close(v, "evicted for a new client");
        }
        w->waiting = 0;
        nwait--;
        nconns++;
        log_info("tcp %s: got a slot after %llu ms (%d clients)", w->peer, (unsigned long long)(now - w->accepted),
                 nconns);
        process(w);
    }
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
    for (;;) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        int fd = accept4(lfd, (struct sockaddr *)&ss, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        char host[48] = "?", serv[8] = "?", lk[80];
        if (fd < 0) {
            if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
                refusal_log("tcp accept: %s; listeners paused for 100 ms", strerror(errno));
                pause_listeners();
            } else if (errno != EAGAIN && errno != EINTR && errno != ECONNABORTED) {
                log_warn("tcp accept: %s", strerror(errno));
            }
            return;
        }
        getnameinfo((struct sockaddr *)&ss, sl, host, sizeof host, serv, sizeof serv,
                    NI_NUMERICHOST | NI_NUMERICSERV);
        listen_key(l, lk, sizeof lk);
        if (!conf_allowed(l, (struct sockaddr *)&ss)) {
            refusal_log("tcp %s:%s: refused: not in the allow-list of listener %s%s%s", host, serv,
                        l->name[0] ? l->name : "", l->name[0] ? " " : "", lk);
            close(fd);
            continue;
        }
        if (nconns >= max_clients && nwait >= WAIT_MAX) {
            /* The oldest waiting newcomer makes room for this one. */
            struct conn *c, *old = NULL;
            for (c = conns; c; c = c->next)
                if (c->waiting && (!old || c->accepted < old->accepted))
                    old = c;
            if (old)
                conn_close(old, "no slot; pushed out by a newer connection");
        }
        struct conn *c = calloc(1, sizeof *c);
        modbus_t *ctx = modbus_new_tcp_pi(NULL, "502");
        if (!c || !ctx || mb_session_init(&c->s, ctx, 1)) {
            log_err("tcp: out of memory");
            if (ctx)
                modbus_free(ctx);
            free(c);
            close(fd);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        set_keepalive(fd);
        modbus_set_socket(ctx, fd);
        c->fd = fd;
        c->accepted = c->last_rx = loop_now_ms();
        c->last_req = loop_now_us();
        c->sa = ss;
        c->s.read_only = l->read_only;
        snprintf(c->laddr, sizeof c->laddr, "%s", lk);
        snprintf(c->peer, sizeof c->peer, "%s:%s", host, serv);
        snprintf(c->s.who, sizeof c->s.who, "tcp %s (listener %s)", c->peer, lk);
        /* Behind connections already waiting, even if a slot just freed:
         * admit() hands slots out oldest first. */
        c->waiting = nconns >= max_clients || nwait > 0;
        c->next = conns;
        conns = c;
        loop_add_fd(fd, POLLIN, on_conn, c);
        if (c->waiting) {
            nwait++;
            log_info("tcp %s: connected, waiting for a slot (%d clients, max_clients)", c->peer, nconns);
        } else {
            nconns++;
            log_info("tcp %s: connected (%d clients)", c->peer, nconns);
        }
    }
}

/* Every 100 ms: idle and byte (incomplete request) timeouts; newcomers
 * that got no slot within WAIT_MS are closed; waiting ones are admitted
 * as connections become idle long enough. */
static void sweep(void *arg)
{
    uint64_t now = loop_now_ms();
    struct conn *c = conns, *next;
    (void)arg;
    for (; c; c = next) {
        next = c->next;
        if (c->partial_since && now - c->partial_since > (uint64_t)byte_ms)
            conn_close(c, "byte timeout: request incomplete");
        else if (c->waiting && now - c->accepted > WAIT_MS) {
            refusal_log("tcp %s: refused: no slot within %d ms, all %d in use by active clients (max_clients)",
                        c->peer, WAIT_MS, max_clients);
            conn_close(c, "no slot");
        } else if (!c->waiting && !c->s.held_len && now - c->last_rx > (uint64_t)idle_ms)
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
        if (bind(fd, ai->ai_addr, ai->ai_addrlen) == 0 && listen(fd, 64) == 0)
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

static void set_opts(const struct conf *c, const struct mb_opts *o)
{
    opts = *o;
    max_clients = c->max_clients;
    idle_ms = c->idle_timeout * 1000;
    byte_ms = c->byte_timeout;
    keepalive_s = c->tcp_keepalive;
    evict_ms = c->evict_idle;
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

int mb_tcp_start(const struct conf *c, const struct mb_opts *o)
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
            if (!conf_allowed(&cf->listen[k], (const struct sockaddr *)&c->sa)) {
                log_notice("tcp %s: closed: no longer in the allow-list of listener %s", c->peer, lk);
                conn_close(c, "not allowed after reload");
            } else {
                c->s.read_only = cf->listen[k].read_only;
            }
            break;
        }
    }
}

int mb_tcp_reload(const struct conf *c, const struct mb_opts *o)
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
    return nconns;
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
