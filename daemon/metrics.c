/* metrics.c — see metrics.h. */
#include "metrics.h"

#include <errno.h>
#include <microhttpd.h>
#include <netdb.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "it2n_regmap.h"
#include "links.h"
#include "log.h"
#include "loop.h"
#include "mb_tcp.h"
#include "models.h"
#include "porthint.h"
#include "store.h"

/* The project's version, from the file VERSION (the Makefile passes it). */
#ifndef IT2N_VERSION
#error "IT2N_VERSION undefined: build with the top-level Makefile (-DIT2N_VERSION from VERSION)"
#endif
#define IT2ND_VERSION IT2N_VERSION

/* A scrape is a few kB; these bound what HTTP clients may hold. */
#define METRICS_MAX_CONNS 8
#define METRICS_TIMEOUT_S 10

static struct MHD_Daemon *mhd;
static int listen_fd = -1, epoll_fd = -1;
static long mhd_timer;
static const struct conf *mcfg;
static char addr[96];

/* Modbus replies by function and result (loop thread only). */
static const struct {
    int fc;
    const char *name;
} funcs[] = {
    {3, "read_holding_registers"},    {4, "read_input_registers"},           {6, "write_single_register"},
    {16, "write_multiple_registers"}, {23, "read_write_multiple_registers"}, {-1, "other"},
};
static const struct {
    int exc;
    const char *name;
} results[] = {
    {0, "ok"},
    {1, "illegal_function"},
    {2, "illegal_data_address"},
    {3, "illegal_data_value"},
    {4, "server_device_failure"},
    {6, "server_device_busy"},
    {11, "gateway_target_failed"},
    {-1, "other_exception"},
};
#define NFUNCS (sizeof funcs / sizeof funcs[0])
#define NRESULTS (sizeof results / sizeof results[0])
static uint64_t mb_count[NFUNCS][NRESULTS];

/* WAL fsync histogram (written by the writer thread). */
static const double fsync_le[] = {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025,
                                  0.05,   0.1,     0.25,   0.5,   1,      2.5,   5,    10};
#define NLE (sizeof fsync_le / sizeof fsync_le[0])
static pthread_mutex_t fsync_mu = PTHREAD_MUTEX_INITIALIZER;
static uint64_t fsync_bucket[NLE], fsync_count, fsync_sum_us, fsync_failed;

void metrics_modbus_reply(int fc, int exc)
{
    size_t f = 0, r = 0;
    while (f < NFUNCS - 1 && funcs[f].fc != fc)
        f++;
    while (r < NRESULTS - 1 && results[r].exc != exc)
        r++;
    mb_count[f][r]++;
}

void metrics_wal_fsync(uint64_t us, int ok)
{
    pthread_mutex_lock(&fsync_mu);
    for (size_t k = 0; k < NLE; k++)
        if ((double)us <= fsync_le[k] * 1e6) {
            fsync_bucket[k]++;
            break;
        }
    fsync_count++;
    fsync_sum_us += us;
    fsync_failed += !ok;
    pthread_mutex_unlock(&fsync_mu);
}

/* A growing text buffer; out of memory sticks (render returns NULL). */
struct buf {
    char *p;
    size_t len, cap;
    int oom;
};

static void put(struct buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void put(struct buf *b, const char *fmt, ...)
{
    va_list ap;
    int n;
    if (b->oom)
        return;
    for (;;) {
        va_start(ap, fmt);
        n = vsnprintf(b->p + b->len, b->cap - b->len, fmt, ap);
        va_end(ap);
        if (n < 0) {
            b->oom = 1;
            return;
        }
        if ((size_t)n < b->cap - b->len) {
            b->len += (size_t)n;
            return;
        }
        size_t cap = b->cap * 2 + (size_t)n;
        char *p = realloc(b->p, cap);
        if (!p) {
            b->oom = 1;
            return;
        }
        b->p = p;
        b->cap = cap;
    }
}

static void family(struct buf *b, const char *name, const char *type, const char *help)
{
    put(b, "# HELP %s %s\n# TYPE %s %s\n", name, help, name, type);
}

/* Label values here are model ids, fixed names and link names from the
 * configuration ([link:NAME]); the format escapes \ " and newline. */
static void put_label(struct buf *b, const char *v)
{
    for (; *v; v++) {
        if (*v == '\\' || *v == '"')
            put(b, "\\%c", *v);
        else if (*v == '\n')
            put(b, "\\n");
        else
            put(b, "%c", *v);
    }
}

char *metrics_render(const struct conf *c, size_t *len)
{
    struct buf b = {malloc(8192), 0, 8192, 0};
    struct store_stats st;
    uint64_t bucket[NLE], count, sum_us, failed;
    if (!b.p)
        return NULL;
    b.p[0] = 0;
    family(&b, "it2nd_build_info", "gauge", "Always 1; the labels say which it2nd and register map version serve.");
    put(&b, "it2nd_build_info{version=\"%s\",regmap=\"%u\"} 1\n", IT2ND_VERSION, (unsigned)IT2N_REGMAP_VERSION);

    /* Models as Modbus clients read them: the last durable state. */
    family(&b, "it2nd_model_generation", "gauge",
           "Generation of the model (status register generation): bumped on every solve or update.");
    for (int k = 0; k < models_count(); k++)
        put(&b, "it2nd_model_generation{model=\"%d\"} %u\n", models_at(k)->id,
            (unsigned)models_view(models_at(k))->gen);
    family(&b, "it2nd_model_points", "gauge", "Data points present for the current configuration (points_present).");
    for (int k = 0; k < models_count(); k++)
        put(&b, "it2nd_model_points{model=\"%d\"} %u\n", models_at(k)->id, models_present(models_view(models_at(k))));
    family(&b, "it2nd_model_points_required", "gauge", "Data points a complete model needs (points_required).");
    for (int k = 0; k < models_count(); k++)
        put(&b, "it2nd_model_points_required{model=\"%d\"} %u\n", models_at(k)->id,
            models_required(models_view(models_at(k))));
    family(&b, "it2nd_model_solved", "gauge", "1 when the model is solved (status register state = 2), else 0.");
    for (int k = 0; k < models_count(); k++)
        put(&b, "it2nd_model_solved{model=\"%d\"} %d\n", models_at(k)->id,
            models_view(models_at(k))->state == IT2N_REGMAP_STATE_SOLVED);
    family(&b, "it2nd_model_points_received_total", "counter", "Data points accepted since start (links and Modbus).");
    for (int k = 0; k < models_count(); k++)
        put(&b, "it2nd_model_points_received_total{model=\"%d\"} %u\n", models_at(k)->id,
            (unsigned)models_view(models_at(k))->points_rx);
    family(&b, "it2nd_model_solves_total", "counter", "Successful full solves since start.");
    for (int k = 0; k < models_count(); k++)
        put(&b, "it2nd_model_solves_total{model=\"%d\"} %u\n", models_at(k)->id,
            (unsigned)models_view(models_at(k))->solves);

    family(&b, "it2nd_modbus_requests_total", "counter",
           "Modbus replies sent since start, by request function and result (ok or the exception).");
    for (size_t f = 0; f < NFUNCS; f++)
        for (size_t r = 0; r < NRESULTS; r++)
            if (mb_count[f][r] || r == 0)
                put(&b, "it2nd_modbus_requests_total{function=\"%s\",result=\"%s\"} %llu\n", funcs[f].name,
                    results[r].name, (unsigned long long)mb_count[f][r]);
    family(&b, "it2nd_connections", "gauge", "Open connections now: Modbus TCP clients, instrument links up.");
    put(&b, "it2nd_connections{transport=\"tcp\"} %d\n", mb_tcp_clients());
    put(&b, "it2nd_connections{transport=\"link\"} %d\n", links_up());

    family(&b, "it2nd_link_frames_sent_total", "counter", "Frames handed to the link's device.");
    for (int k = 0; c && k < c->nlinks; k++) {
        struct links_out_stats ls;
        if (links_out_stats(k, &ls))
            continue;
        put(&b, "it2nd_link_frames_sent_total{link=\"");
        put_label(&b, c->link[k].name);
        put(&b, "\"} %u\n", (unsigned)ls.frames);
    }
    family(&b, "it2nd_link_frames_dropped_total", "counter",
           "Frames dropped whole because the link's output queue was full.");
    for (int k = 0; c && k < c->nlinks; k++) {
        struct links_out_stats ls;
        if (links_out_stats(k, &ls))
            continue;
        put(&b, "it2nd_link_frames_dropped_total{link=\"");
        put_label(&b, c->link[k].name);
        put(&b, "\"} %u\n", (unsigned)ls.dropped);
    }

    store_get_stats(&st);
    family(&b, "it2nd_store_degraded", "gauge",
           "1 while the store is degraded after an I/O error (every write refused until a checkpoint succeeds).");
    put(&b, "it2nd_store_degraded %d\n", store_degraded());
    family(&b, "it2nd_wal_records_total", "counter", "WAL records committed since start.");
    put(&b, "it2nd_wal_records_total %llu\n", (unsigned long long)st.records);
    family(&b, "it2nd_wal_commits_total", "counter",
           "WAL group commits (one write and one fdatasync each) since start.");
    put(&b, "it2nd_wal_commits_total %llu\n", (unsigned long long)st.commits);
    family(&b, "it2nd_snapshots_total", "counter", "Checkpoints (snapshot and new WAL) written since start.");
    put(&b, "it2nd_snapshots_total %llu\n", (unsigned long long)st.snapshots);
    family(&b, "it2nd_wal_bytes", "gauge", "Bytes in the WAL since the last snapshot.");
    put(&b, "it2nd_wal_bytes %llu\n", (unsigned long long)store_wal_bytes());
    family(&b, "it2nd_wal_records_dropped_total", "counter",
           "WAL records that did not validate at start-up recovery (a torn last commit).");
    put(&b, "it2nd_wal_records_dropped_total %llu\n", (unsigned long long)st.dropped);

    pthread_mutex_lock(&fsync_mu);
    memcpy(bucket, fsync_bucket, sizeof bucket);
    count = fsync_count;
    sum_us = fsync_sum_us;
    failed = fsync_failed;
    pthread_mutex_unlock(&fsync_mu);
    family(&b, "it2nd_wal_fsync_duration_seconds", "histogram",
           "Duration of every WAL fsync/fdatasync (group commits and new WAL files).");
    {
        uint64_t cum = 0;
        for (size_t k = 0; k < NLE; k++) {
            cum += bucket[k];
            put(&b, "it2nd_wal_fsync_duration_seconds_bucket{le=\"%g\"} %llu\n", fsync_le[k], (unsigned long long)cum);
        }
    }
    put(&b, "it2nd_wal_fsync_duration_seconds_bucket{le=\"+Inf\"} %llu\n", (unsigned long long)count);
    put(&b, "it2nd_wal_fsync_duration_seconds_sum %.6f\n", (double)sum_us / 1e6);
    put(&b, "it2nd_wal_fsync_duration_seconds_count %llu\n", (unsigned long long)count);
    family(&b, "it2nd_wal_fsync_failures_total", "counter", "WAL fsyncs that failed (each degrades the store).");
    put(&b, "it2nd_wal_fsync_failures_total %llu\n", (unsigned long long)failed);
    if (b.oom) {
        free(b.p);
        return NULL;
    }
    *len = b.len;
    return b.p;
}

static enum MHD_Result queue(struct MHD_Connection *conn, unsigned status, const char *text, const char *type)
{
    struct MHD_Response *r = MHD_create_response_from_buffer(strlen(text), (void *)text, MHD_RESPMEM_PERSISTENT);
    enum MHD_Result rc;
    if (!r)
        return MHD_NO;
    MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE, type);
    rc = MHD_queue_response(conn, status, r);
    MHD_destroy_response(r);
    return rc;
}

static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url, const char *method,
                                  const char *version, const char *upload, size_t *upload_size, void **ctx)
{
    struct MHD_Response *r;
    enum MHD_Result rc;
    size_t len = 0;
    char *text;
    (void)cls;
    (void)version;
    (void)upload;
    if (!*ctx) { /* headers only so far: answer on the next call */
        *ctx = (void *)1;
        return MHD_YES;
    }
    if (*upload_size) { /* a body: ignored (GET has none) */
        *upload_size = 0;
        return MHD_YES;
    }
    if (strcmp(url, "/metrics"))
        return queue(conn, MHD_HTTP_NOT_FOUND, "not found: it2nd serves /metrics only\n", "text/plain; charset=utf-8");
    if (strcmp(method, MHD_HTTP_METHOD_GET) && strcmp(method, MHD_HTTP_METHOD_HEAD))
        return queue(conn, MHD_HTTP_METHOD_NOT_ALLOWED, "method not allowed: use GET\n", "text/plain; charset=utf-8");
    text = metrics_render(mcfg, &len);
    if (!text)
        return queue(conn, MHD_HTTP_INTERNAL_SERVER_ERROR, "out of memory\n", "text/plain; charset=utf-8");
    r = MHD_create_response_from_buffer(len, text, MHD_RESPMEM_MUST_FREE);
    if (!r) {
        free(text);
        return MHD_NO;
    }
    MHD_add_response_header(r, MHD_HTTP_HEADER_CONTENT_TYPE, "text/plain; version=0.0.4; charset=utf-8");
    rc = MHD_queue_response(conn, MHD_HTTP_OK, r);
    MHD_destroy_response(r);
    return rc;
}

static void on_mhd_log(void *cls, const char *fmt, va_list ap)
{
    char msg[256];
    (void)cls;
    vsnprintf(msg, sizeof msg, fmt, ap);
    msg[strcspn(msg, "\n")] = 0;
    log_debug("metrics: %s", msg);
}

static void on_timer(void *arg);

/* Let libmicrohttpd do what is ready (never blocks: its sockets are
 * non-blocking), then wake again when it has a timeout to enforce or
 * buffered work (0 ms), at the latest in a second. */
static void run_mhd(void)
{
    MHD_UNSIGNED_LONG_LONG ms = 1000;
    if (!mhd)
        return;
    MHD_run(mhd);
    if (mhd_timer)
        loop_cancel_timer(mhd_timer);
    if (MHD_get_timeout(mhd, &ms) != MHD_YES || ms > 1000)
        ms = 1000;
    mhd_timer = loop_add_timer((uint64_t)ms, on_timer, NULL);
}

static void on_timer(void *arg)
{
    (void)arg;
    mhd_timer = 0;
    run_mhd();
}

static void on_epoll(void *arg, int fd, short revents)
{
    (void)arg;
    (void)fd;
    (void)revents;
    run_mhd();
}

const char *metrics_address(void)
{
    return addr;
}

/* The listening socket, bound here (not by libmicrohttpd) for the same
 * address handling and error messages as the Modbus listeners. */
static int open_socket(const struct conf_metrics *m)
{
    struct addrinfo hints, *res = NULL, *ai;
    int fd = -1, rc, e = 0;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    rc = getaddrinfo(m->host[0] ? m->host : NULL, m->port, &hints, &res);
    if (rc) {
        log_err("metrics listen %s: %s", addr, gai_strerror(rc));
        return -1;
    }
    for (ai = res; ai; ai = ai->ai_next) {
        int one = 1, v6only = m->host[0] ? 1 : 0;
        if (!m->host[0] && ai->ai_family != AF_INET6 && ai->ai_next)
            continue;
        fd = socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
        if (fd < 0) {
            e = errno;
            continue;
        }
        setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
        if (ai->ai_family == AF_INET6)
            setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &v6only, sizeof v6only);
        if (bind(fd, ai->ai_addr, ai->ai_addrlen) == 0 && listen(fd, 16) == 0)
            break;
        e = errno;
        close(fd);
        fd = -1;
    }
    freeaddrinfo(res);
    if (fd < 0) {
        char hint[320] = "";
        if (e == EADDRINUSE)
            porthint_in_use(m->host, m->port, "it2nd --metrics HOST:PORT, or [metrics] listen", hint, sizeof hint);
        log_err("metrics listen %s: %s%s%s", addr, strerror(e), hint[0] ? ": " : "", hint);
    }
    return fd;
}

int metrics_start(const struct conf *c)
{
    const union MHD_DaemonInfo *info;
    int v6 = strchr(c->metrics.host, ':') != NULL;
    mcfg = c;
    addr[0] = 0;
    if (!c->metrics.port[0])
        return 0;
    snprintf(addr, sizeof addr, "%s%s%s:%s", v6 ? "[" : "", c->metrics.host, v6 ? "]" : "", c->metrics.port);
    listen_fd = open_socket(&c->metrics);
    if (listen_fd < 0)
        return -1;
    /* No internal thread (see metrics.h): MHD_USE_EPOLL without
     * MHD_USE_INTERNAL_POLLING_THREAD is the external-loop mode. */
    mhd = MHD_start_daemon(MHD_USE_EPOLL | MHD_USE_ERROR_LOG | (v6 ? MHD_USE_IPv6 : 0), 0, NULL, NULL, on_request, NULL,
                           MHD_OPTION_LISTEN_SOCKET, (MHD_socket)listen_fd, MHD_OPTION_CONNECTION_LIMIT,
                           (unsigned)METRICS_MAX_CONNS, MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)METRICS_TIMEOUT_S,
                           MHD_OPTION_EXTERNAL_LOGGER, on_mhd_log, NULL, MHD_OPTION_SIGPIPE_HANDLED_BY_APP, 1,
                           MHD_OPTION_END);
    if (!mhd) {
        log_err("metrics listen %s: libmicrohttpd did not start", addr);
        metrics_stop();
        return -1;
    }
    info = MHD_get_daemon_info(mhd, MHD_DAEMON_INFO_EPOLL_FD);
    epoll_fd = info ? info->epoll_fd : -1;
    if (epoll_fd < 0 || loop_add_fd(epoll_fd, POLLIN, on_epoll, NULL)) {
        log_err("metrics listen %s: cannot watch libmicrohttpd's epoll fd", addr);
        metrics_stop();
        return -1;
    }
    run_mhd();
    log_notice("metrics: Prometheus endpoint on http://%s/metrics", addr);
    return 0;
}

void metrics_stop(void)
{
    if (mhd_timer)
        loop_cancel_timer(mhd_timer);
    mhd_timer = 0;
    if (epoll_fd >= 0)
        loop_del_fd(epoll_fd);
    epoll_fd = -1;
    if (mhd)
        MHD_stop_daemon(mhd); /* closes listen_fd, which it was given */
    else if (listen_fd >= 0)
        close(listen_fd);
    mhd = NULL;
    listen_fd = -1;
}
