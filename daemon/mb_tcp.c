/* mb_tcp.c — see mb_tcp.h. */
#include "mb_tcp.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
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

struct conn {
    int fd;
    struct mb_session s;
    uint8_t buf[MODBUS_TCP_MAX_ADU_LENGTH * 2];
    size_t len;
    uint64_t last_rx;      /* ms, for the idle timeout */
    uint64_t partial_since; /* ms, first byte of an incomplete request, 0 none */
    char peer[64];
    struct conn *next;
};

static int listen_fd[CONF_MAX_LISTEN];
static struct conf_listen listen_addr[CONF_MAX_LISTEN];
static int nlisten;
static struct conn *conns;
static int nconns;
static struct mb_opts opts;
static int max_clients, idle_ms, byte_ms;
static long sweep_timer;

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
    nconns--;
    free(c);
}

/* Frame and handle every complete request in the buffer. Stops at a held
 * request (its reply, and so any later request, waits for the commit). */
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
        if (mb_req_handle(&c->s, c->buf, (int)total, &opts) < 0) {
            conn_close(c, "send failed");
            return -1;
        }
        memmove(c->buf, c->buf + total, c->len - total);
        c->len -= total;
    }
    c->partial_since = c->len ? (c->partial_since ? c->partial_since : loop_now_ms()) : 0;
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

static void on_accept(void *arg, int lfd, short revents)
{
    (void)arg;
    (void)revents;
    for (;;) {
        struct sockaddr_storage ss;
        socklen_t sl = sizeof ss;
        int fd = accept4(lfd, (struct sockaddr *)&ss, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        char host[48] = "?", serv[8] = "?";
        if (fd < 0) {
            if (errno != EAGAIN && errno != EINTR)
                log_warn("tcp accept: %s", strerror(errno));
            return;
        }
        getnameinfo((struct sockaddr *)&ss, sl, host, sizeof host, serv, sizeof serv,
                    NI_NUMERICHOST | NI_NUMERICSERV);
        if (nconns >= max_clients) {
            log_warn("tcp %s:%s: refused, %d clients (max_clients)", host, serv, nconns);
            close(fd);
            continue;
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
        modbus_set_socket(ctx, fd);
        c->fd = fd;
        c->last_rx = loop_now_ms();
        snprintf(c->peer, sizeof c->peer, "%s:%s", host, serv);
        c->next = conns;
        conns = c;
        nconns++;
        loop_add_fd(fd, POLLIN, on_conn, c);
        log_info("tcp %s: connected (%d clients)", c->peer, nconns);
    }
}

/* Every 100 ms: idle and byte (incomplete request) timeouts. */
static void sweep(void *arg)
{
    uint64_t now = loop_now_ms();
    struct conn *c = conns, *next;
    (void)arg;
    for (; c; c = next) {
        next = c->next;
        if (c->partial_since && now - c->partial_since > (uint64_t)byte_ms)
            conn_close(c, "byte timeout: request incomplete");
        else if (!c->s.held_len && now - c->last_rx > (uint64_t)idle_ms)
            conn_close(c, "idle timeout");
    }
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
        log_err("tcp listen %s:%s: %s", l->host, l->port, strerror(errno));
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd >= 0)
        log_notice("modbus tcp listening on %s%s%s:%s", strchr(l->host, ':') ? "[" : "",
                   l->host[0] ? l->host : "*", strchr(l->host, ':') ? "]" : "", l->port);
    return fd;
}

static void set_opts(const struct conf *c, const struct mb_opts *o)
{
    opts = *o;
    max_clients = c->max_clients;
    idle_ms = c->idle_timeout * 1000;
    byte_ms = c->byte_timeout;
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
        nlisten++;
        loop_add_fd(fd, POLLIN, on_accept, NULL);
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

int mb_tcp_reload(const struct conf *c, const struct mb_opts *o)
{
    int same = c->nlisten == nlisten;
    for (int k = 0; same && k < nlisten; k++)
        same = !strcmp(c->listen[k].host, listen_addr[k].host) && !strcmp(c->listen[k].port, listen_addr[k].port);
    set_opts(c, o);
    if (same)
        return 0;
    log_notice("tcp: listen addresses changed; reopening listeners (connections kept)");
    close_listeners();
    return open_listeners(c);
}

void mb_tcp_release(int commit_ok)
{
    struct conn *c = conns, *next;
    for (; c; c = next) {
        next = c->next;
        if (!c->s.held_len)
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
}
