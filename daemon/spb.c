/* spb.c — see spb.h. The session (connect, births, data, commands, death)
 * and the node's own metrics; the devices' metrics are spb_metrics.c's,
 * DCMD handling spb_dcmd.c's. */
#include "spb.h"

#include <errno.h>
#include <fcntl.h>
#include <mosquitto.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "log.h"
#include "loop.h"
#include "mb_map.h"
#include "models.h"
#include "spb_dcmd.h"
#include "spb_metrics.h"
#include "spb_payload.h"
#include "spb_sf.h"

#define NS "spBv1.0"
#define BDSEQ_FILE "sparkplug.bdseq"
#define BACKOFF_FIRST_MS 500
#define TICK_MS 1000      /* keep-alive check and the status scan */
#define STOP_WAIT_MS 2000 /* NDEATH PUBACK at a graceful stop     */
#define SF_BATCH 32       /* historical DDATA per loop pass       */

/* Node metrics (NBIRTH), by alias. Device metrics have the aliases
 * (model id + 1) * SPB_DEV_ALIAS + index: unique on the node, readable. */
enum { NA_BDSEQ = 1, NA_REBIRTH, NA_VERSION, NA_MAP_VERSION, NA_MODELS, NA_SF_DROPPED, NA_COUNT = NA_SF_DROPPED };

enum st { ST_IDLE, ST_CONNECTING, ST_ONLINE };

struct dev {
    int id;
    int dirty;                    /* a change was signalled: scan it      */
    int based;                    /* last holds values a host has or will have */
    struct spb_payload_val *last; /* values as last published             */
    struct mb_map_query q;        /* its query (DCMD), like a Modbus connection's */
};

static struct {
    int on;
    struct spb_conf sc;
    char state_dir[CONF_PATH];
    char version[64];
    char client_id[2 * SPB_ID_MAX + 8];
    char t_nbirth[160], t_ndeath[160], t_ncmd[160], t_dpre[4][160], t_dcmd_sub[160];
    struct mosquitto *mosq;
    enum st st;
    int fd;     /* the socket the loop watches, or -1   */
    int parked; /* a TLS socket that failed while connecting: not watched */
    short events;
    long retry_timer, tick_timer;
    int backoff_ms;
    int file_bd; /* bdSeq in state_dir (-1: none yet)    */
    int next_bd; /* bdSeq of the next CONNECT            */
    int bdseq;   /* bdSeq of the current session         */
    int seq;     /* seq of the next message after NBIRTH */
    int dropped; /* on_disconnect since the last check   */
    int ndeath_mid, ndeath_acked;
    int need_birth;         /* a birth sequence is incomplete       */
    struct mb_map_opts mbo; /* the grid as Modbus serves it, ABCD   */
    struct dev *devs;
    int ndevs;
    unsigned long births, ddata;
    /* Primary host (Sparkplug 3.0 STATE) and store-and-forward. */
    int use_host; /* primary_host_id is set               */
    char t_state[160];
    int host_on;      /* its last STATE this session: online  */
    uint64_t host_ts; /* timestamp of the last online STATE   */
    int leaving;      /* NDEATH + DISCONNECT: the host went offline */
    int sf_max;       /* store_forward_max in effect (0: off) */
    int sf_flushing;  /* stored changes are being published   */
    uint64_t sf_off;  /* the next stored record to publish    */
    unsigned long sf_dropped, sf_stored, sf_sent;
} g = {.fd = -1, .parked = -1};

enum { TP_DBIRTH, TP_DDATA, TP_DDEATH, TP_DCMD };

/* ---- publishing ---- */

static uint64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static void sync_fd(void);
static void on_fd(void *arg, int fd, short revents);

/* Pack and publish (QoS 0, not retained unless said): seq < 0 none. */
static int publish(const char *topic, struct spb_payload *pl, uint64_t ts, int seq, int qos, int *mid)
{
    uint8_t *buf;
    size_t len;
    int rc;
    if (spb_payload_pack(pl, ts, seq, &buf, &len)) {
        log_err("sparkplug: out of memory encoding %s", topic);
        return -1;
    }
    rc = mosquitto_publish(g.mosq, mid, topic, (int)len, buf, qos, false);
    free(buf);
    if (rc != MOSQ_ERR_SUCCESS) {
        log_warn("sparkplug: publish %s: %s", topic, mosquitto_strerror(rc));
        return -1;
    }
    return 0;
}

/* Publish with the next seq, taken only when the message is queued: a
 * failed publish leaves no gap a host would read as a lost message. */
static int publish_seq(const char *topic, struct spb_payload *pl, uint64_t ts)
{
    if (publish(topic, pl, ts, g.seq, 0, NULL))
        return -1;
    g.seq = (g.seq + 1) & 255;
    return 0;
}

static void dev_topic(char *buf, size_t size, int kind, int id)
{
    snprintf(buf, size, "%s%d", g.t_dpre[kind], id);
}

static struct dev *dev_find(int id)
{
    for (int k = 0; k < g.ndevs; k++)
        if (g.devs[k].id == id)
            return &g.devs[k];
    return NULL;
}

static void devs_free(void)
{
    for (int k = 0; k < g.ndevs; k++)
        free(g.devs[k].last);
    free(g.devs);
    g.devs = NULL;
    g.ndevs = 0;
}

/* The device table follows the model table (births, reload). */
static int devs_build(void)
{
    int n = models_count(), nm = spb_metrics_count(&g.mbo);
    struct dev *old = g.devs;
    int nold = g.ndevs;
    g.devs = calloc((size_t)(n ? n : 1), sizeof *g.devs);
    g.ndevs = 0;
    if (!g.devs) {
        g.devs = old;
        g.ndevs = nold;
        return -1;
    }
    for (int k = 0; k < n; k++) {
        g.devs[k].id = models_at(k)->id;
        /* A query outlives a birth, not its model (a removed and re-added
         * model is a new one: its cached results are keyed on instance). */
        for (int j = 0; j < nold; j++)
            if (old[j].id == g.devs[k].id)
                g.devs[k].q = old[j].q;
        g.devs[k].last = calloc((size_t)nm, sizeof *g.devs[k].last);
        if (!g.devs[k].last)
            break;
        g.ndevs = k + 1;
    }
    for (int j = 0; j < nold; j++)
        free(old[j].last);
    free(old);
    return g.ndevs == n ? 0 : -1;
}

static int nbirth(void)
{
    struct spb_payload *pl = spb_payload_new(NA_COUNT);
    uint64_t ts = now_ms();
    struct spb_payload_val v;
    int rc = -1;
    char ver[96];
    if (!pl)
        return -1;
    snprintf(ver, sizeof ver, "it2nd %s", g.version);
    memset(&v, 0, sizeof v);
    v.u = (uint64_t)g.bdseq;
    spb_payload_add(pl, "bdSeq", NA_BDSEQ, SPB_PAYLOAD_INT64, ts, &v);
    v.u = 0;
    spb_payload_add(pl, "Node Control/Rebirth", NA_REBIRTH, SPB_PAYLOAD_BOOLEAN, ts, &v);
    v.s = ver;
    spb_payload_add(pl, "Properties/Software Version", NA_VERSION, SPB_PAYLOAD_STRING, ts, &v);
    v.s = NULL;
    v.u = IT2N_REGMAP_VERSION;
    spb_payload_prop(pl,
                     spb_payload_add(pl, "Properties/Register Map Version", NA_MAP_VERSION, SPB_PAYLOAD_UINT16, ts, &v),
                     "description", "Layout version of the Modbus register map the device metrics mirror");
    v.u = (uint64_t)models_count();
    spb_payload_prop(pl, spb_payload_add(pl, "Properties/Models", NA_MODELS, SPB_PAYLOAD_UINT32, ts, &v), "description",
                     "Devices (models) served by this edge node, each as model-N");
    if (g.sf_max) {
        v.u = (uint64_t)g.sf_dropped;
        spb_payload_prop(
            pl, spb_payload_add(pl, "Store and Forward/Dropped", NA_SF_DROPPED, SPB_PAYLOAD_UINT64, ts, &v),
            "description",
            "Changes not kept for the host's history since start: the store (store_forward_max) was full or "
            "could not be written (each is logged)");
    }
    g.seq = 0;
    rc = publish_seq(g.t_nbirth, pl, ts);
    spb_payload_free(pl);
    return rc;
}

static int dbirth(struct dev *d, struct model *md)
{
    int nm = spb_metrics_count(&g.mbo), rc;
    struct spb_payload *pl = spb_payload_new((size_t)nm);
    uint64_t ts = now_ms();
    char topic[200], name[96], desc[200];
    if (!pl)
        return -1;
    spb_metrics_values(models_view(md), &d->q, &g.mbo, d->last);
    for (int k = 0; k < nm; k++) {
        const char *unit;
        int idx;
        spb_metrics_info(&g.mbo, k, name, sizeof name, desc, sizeof desc, &unit);
        idx = spb_payload_add(pl, name, (uint64_t)(d->id + 1) * SPB_DEV_ALIAS + (uint64_t)k, spb_metrics_type(k), ts,
                              &d->last[k]);
        if (idx < 0 || spb_payload_prop(pl, idx, "description", desc) ||
            (unit && spb_payload_prop(pl, idx, "engUnit", unit))) {
            spb_payload_free(pl);
            return -1;
        }
    }
    dev_topic(topic, sizeof topic, TP_DBIRTH, d->id);
    rc = publish_seq(topic, pl, ts);
    spb_payload_free(pl);
    d->dirty = 0;
    d->based = 1;
    return rc;
}

/* NBIRTH at seq 0, then one DBIRTH per model (a new connection, a
 * Rebirth command, a reload that changed the metric set). */
static void births(void)
{
    /* Until a whole sequence is out, no DDATA (its aliases would not be
     * born): an incomplete one is tried again from the loop hook. */
    g.need_birth = 1;
    if (g.use_host && !g.host_on)
        return; /* spec 3.0: no birth before the primary host is online */
    if (devs_build()) {
        log_err("sparkplug: out of memory building the device table");
        return;
    }
    if (nbirth())
        return;
    for (int k = 0; k < g.ndevs; k++) {
        struct model *md = models_by_id(g.devs[k].id);
        if (md && dbirth(&g.devs[k], md))
            return;
    }
    g.need_birth = 0;
    g.births++;
    log_info("sparkplug: NBIRTH and %d DBIRTH published (bdSeq %d)", g.ndevs, g.bdseq);
    /* What was stored while the host or the broker was away follows the
     * births (its aliases are born), oldest first. */
    g.sf_off = 0;
    g.sf_flushing = g.sf_max && spb_sf_count() > 0;
    if (g.sf_flushing)
        log_info("sparkplug: publishing %d stored change(s) as historical DDATA", spb_sf_count());
}

/* Report by exception: a DDATA with the metrics whose value moved since
 * the last birth or DDATA of the device, by alias. */
static void dev_scan(struct dev *d)
{
    struct model *md = models_by_id(d->id);
    int nm = spb_metrics_count(&g.mbo), n = 0;
    struct spb_payload_val *cur;
    struct spb_payload *pl;
    uint64_t ts = now_ms();
    char topic[200];
    d->dirty = 0;
    if (!md || !(cur = malloc((size_t)nm * sizeof *cur)))
        return;
    spb_metrics_values(models_view(md), &d->q, &g.mbo, cur);
    for (int k = 0; k < nm; k++)
        n += !spb_payload_val_equal(spb_metrics_type(k), &cur[k], &d->last[k]);
    /* Sized for what changed: the 1 s scan of an unchanged device costs
     * the comparison only. */
    pl = n ? spb_payload_new((size_t)n) : NULL;
    for (int k = 0; pl && k < nm; k++)
        if (!spb_payload_val_equal(spb_metrics_type(k), &cur[k], &d->last[k]))
            spb_payload_add(pl, NULL, (uint64_t)(d->id + 1) * SPB_DEV_ALIAS + (uint64_t)k, spb_metrics_type(k), ts,
                            &cur[k]);
    if (pl) {
        dev_topic(topic, sizeof topic, TP_DDATA, d->id);
        if (publish_seq(topic, pl, ts) == 0) {
            memcpy(d->last, cur, (size_t)nm * sizeof *cur);
            g.ddata++;
        }
    }
    spb_payload_free(pl);
    free(cur);
}

/* Scan what is due, unless the socket still has output queued (a slow or
 * stopped broker): the changes wait, coalesced, since a DDATA carries the
 * latest values; the queue never grows past one birth sequence. */
static void sf_store(int all);
static void sf_forward(void);

static void scan(int all)
{
    if (g.st != ST_ONLINE || (g.use_host && !g.host_on)) {
        /* Nobody to tell: keep the change for the host's history. */
        if (g.sf_max && !g.leaving)
            sf_store(all);
        return;
    }
    if (mosquitto_want_write(g.mosq))
        return;
    if (g.need_birth) {
        births();
        return;
    }
    if (g.sf_flushing) {
        sf_forward(); /* history first: live changes wait, coalesced */
        return;
    }
    for (int k = 0; k < g.ndevs; k++)
        if (all || g.devs[k].dirty)
            dev_scan(&g.devs[k]);
}

/* ---- store-and-forward ---- */

/* Every device's values now as the baseline of what a host has (or will
 * get in its next birth), for devices without one. */
static void sf_base(void)
{
    if (!g.devs && devs_build()) {
        log_err("sparkplug: out of memory building the device table");
        return;
    }
    for (int k = 0; k < g.ndevs; k++) {
        struct model *md = models_by_id(g.devs[k].id);
        if (!g.devs[k].based && md) {
            spb_metrics_values(models_view(md), &g.devs[k].q, &g.mbo, g.devs[k].last);
            g.devs[k].based = 1;
            g.devs[k].dirty = 0;
        }
    }
}

/* While nobody can be told: each device's metrics that moved since the
 * last birth, DDATA or stored change go to the store, durably. */
static void sf_store(int all)
{
    int nm = spb_metrics_count(&g.mbo);
    struct spb_payload_val *cur = NULL;
    uint16_t *idx = NULL;
    struct spb_payload_val *vals = NULL;
    sf_base();
    for (int k = 0; k < g.ndevs; k++) {
        struct dev *d = &g.devs[k];
        struct model *md = models_by_id(d->id);
        int n = 0, rc;
        if (!(all || d->dirty) || !md)
            continue;
        d->dirty = 0;
        if (!cur && (!(cur = malloc((size_t)nm * sizeof *cur)) || !(idx = malloc((size_t)nm * sizeof *idx)) ||
                     !(vals = malloc((size_t)nm * sizeof *vals)))) {
            log_err("sparkplug: out of memory storing a change");
            break;
        }
        spb_metrics_values(models_view(md), &d->q, &g.mbo, cur);
        /* The nets (FloatArray) are derived from the points, which are
         * kept: the host gets the nets of now in the birth it will have. */
        for (int j = 0; j < nm; j++)
            if (spb_metrics_type(j) != SPB_PAYLOAD_FLOATARRAY &&
                !spb_payload_val_equal(spb_metrics_type(j), &cur[j], &d->last[j])) {
                idx[n] = (uint16_t)j;
                vals[n++] = cur[j];
            }
        if (!n)
            continue;
        rc = spb_sf_append(d->id, now_ms(), n, idx, vals);
        if (rc == 0) {
            g.sf_stored++;
        } else {
            /* Not kept: counted (NBIRTH "Store and Forward/Dropped") and
             * logged; the next birth carries the value, not its history. */
            if (rc > 0 && (g.sf_dropped == 0 || (g.sf_dropped & (g.sf_dropped + 1)) == 0))
                log_warn("sparkplug: store-and-forward full (store_forward_max = %d): a change of model-%d not kept "
                         "for the host's history (%lu dropped since start)",
                         g.sf_max, d->id, g.sf_dropped + 1);
            g.sf_dropped++;
        }
        memcpy(d->last, cur, (size_t)nm * sizeof *cur);
    }
    free(cur);
    free(idx);
    free(vals);
}

/* Publish the next stored changes as historical DDATA; once all are out
 * of the socket, empty the store. */
static void sf_forward(void)
{
    int nm = spb_metrics_count(&g.mbo);
    for (int b = 0; b < SF_BATCH; b++) {
        struct spb_sf_rec rec;
        struct spb_payload *pl;
        char topic[200];
        int rc = spb_sf_read(&g.sf_off, &rec);
        if (rc == 0) {
            if (!mosquitto_want_write(g.mosq)) {
                log_info("sparkplug: %d stored change(s) published as historical DDATA", spb_sf_count());
                spb_sf_clear();
                g.sf_flushing = 0;
            }
            return;
        }
        if (rc < 0) {
            log_err("sparkplug: cannot read the stored changes; they stay in %s", SPB_SF_FILE);
            g.sf_flushing = 0;
            return;
        }
        pl = dev_find(rec.dev) ? spb_payload_new((size_t)rec.n) : NULL;
        for (int k = 0; pl && k < rec.n; k++)
            if (rec.idx[k] < nm)
                spb_payload_add(pl, NULL, (uint64_t)(rec.dev + 1) * SPB_DEV_ALIAS + rec.idx[k],
                                spb_metrics_type(rec.idx[k]), rec.ts, &rec.val[k]);
        if (!pl) {
            log_warn("sparkplug: a stored change of model-%d is not published: the device is gone", rec.dev);
        } else {
            spb_payload_historical(pl);
            dev_topic(topic, sizeof topic, TP_DDATA, rec.dev);
            if (publish_seq(topic, pl, rec.ts) == 0)
                g.sf_sent++;
        }
        spb_payload_free(pl);
        spb_sf_rec_free(&rec);
        if (mosquitto_want_write(g.mosq))
            return;
    }
}

/* ---- bdSeq in state_dir ---- */

static int bdseq_load(void)
{
    char path[CONF_PATH + 32], buf[16];
    int fd, n, v;
    snprintf(path, sizeof path, "%s/%s", g.state_dir, BDSEQ_FILE);
    fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        if (errno == ENOENT)
            return -1;
        log_err("sparkplug: %s: %s", path, strerror(errno));
        return -2;
    }
    n = (int)read(fd, buf, sizeof buf - 1);
    close(fd);
    if (n <= 0 || (buf[n] = 0, sscanf(buf, "%d", &v) != 1) || v < 0 || v > 255) {
        /* Damaged: start past any value a host may have seen is impossible
         * to know; 0 is what a new node would send. Said, not hidden. */
        log_warn("sparkplug: %s does not hold a bdSeq 0..255; starting again at 0", path);
        return -1;
    }
    return v;
}

/* Durably, before the CONNECT that carries it: a restart never sends a
 * bdSeq a host has already seen in this node's last session. */
static int bdseq_save(int v)
{
    char path[CONF_PATH + 32], tmp[CONF_PATH + 40], buf[16];
    int fd, n, ok;
    snprintf(path, sizeof path, "%s/%s", g.state_dir, BDSEQ_FILE);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    n = snprintf(buf, sizeof buf, "%d\n", v);
    fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return -1;
    ok = write(fd, buf, (size_t)n) == n && fsync(fd) == 0;
    close(fd);
    if (!ok || rename(tmp, path)) {
        unlink(tmp);
        return -1;
    }
    fd = open(g.state_dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        ok = fsync(fd) == 0;
        close(fd);
    }
    return ok ? 0 : -1;
}

/* ---- the MQTT session ---- */

static void try_connect(void *arg);

static void schedule_retry(void)
{
    if (g.retry_timer)
        return;
    g.retry_timer = loop_add_timer((uint64_t)g.backoff_ms, try_connect, NULL);
    g.backoff_ms = g.backoff_ms * 2 > g.sc.reconnect_max * 1000 ? g.sc.reconnect_max * 1000 : g.backoff_ms * 2;
}

/* Watch the socket libmosquitto has now (it closes it on errors and opens
 * a new one per attempt), for output only while some is queued. */
static void sync_fd(void)
{
    int fd = g.mosq ? mosquitto_socket(g.mosq) : -1;
    const SSL *ssl = fd >= 0 ? mosquitto_ssl_get(g.mosq) : NULL;
    /* During a TLS handshake the CONNECT is queued but cannot go yet: wait
     * for what OpenSSL wants, not for any writable socket (a busy loop). */
    int out = fd >= 0 && (ssl && !SSL_is_init_finished(ssl) ? SSL_want_write(ssl) : mosquitto_want_write(g.mosq));
    short ev = (short)(POLLIN | (out ? POLLOUT : 0));
    if (fd < 0 || fd != g.parked)
        g.parked = -1;
    else
        fd = -1; /* parked: libmosquitto's keep-alive check closes it */
    if (fd != g.fd) {
        if (g.fd >= 0)
            loop_del_fd(g.fd);
        g.fd = -1;
        if (fd >= 0) {
            if (loop_add_fd(fd, ev, on_fd, NULL) == 0) {
                g.fd = fd;
                g.events = ev;
            }
        }
    } else if (fd >= 0 && ev != g.events) {
        loop_mod_fd(fd, ev);
        g.events = ev;
    }
}

/* After every libmosquitto call: a lost connection goes back to waiting. */
static void after(void)
{
    if (g.dropped || (g.st != ST_IDLE && g.mosq && mosquitto_socket(g.mosq) < 0)) {
        g.dropped = 0;
        g.sf_flushing = 0; /* what was not cleared goes again next time */
        if (g.leaving)
            log_info("sparkplug: disconnected while the primary host %s is offline; waiting for it",
                     g.sc.primary_host_id);
        else if (g.st == ST_ONLINE)
            log_warn("sparkplug: connection to %s:%d lost; reconnecting (at most %d s apart)", g.sc.host, g.sc.port,
                     g.sc.reconnect_max);
        g.st = ST_IDLE;
        g.leaving = 0;
        schedule_retry();
    }
    sync_fd();
}

static void on_fd(void *arg, int fd, short revents)
{
    int rc = MOSQ_ERR_SUCCESS;
    (void)arg;
    (void)fd;
    /* A TLS handshake advances in loop_read, whichever way it waits. */
    if (revents & (POLLIN | POLLERR | POLLHUP | POLLOUT))
        rc = mosquitto_loop_read(g.mosq, 1);
    /* A TLS connection that failed before its handshake: libmosquitto keeps
     * the socket (SSL_ERROR_SYSCALL) until the keep-alive check; stop
     * watching it meanwhile (poll would report it at once, again and again). */
    if (rc == MOSQ_ERR_SUCCESS && (revents & (POLLERR | POLLHUP)) && g.st == ST_CONNECTING && g.sc.tls_ca[0] &&
        mosquitto_socket(g.mosq) >= 0) {
        log_info("sparkplug: %s:%d: connection failed", g.sc.host, g.sc.port);
        g.parked = mosquitto_socket(g.mosq);
    }
    if (rc == MOSQ_ERR_SUCCESS && (revents & POLLOUT) && mosquitto_socket(g.mosq) >= 0)
        rc = mosquitto_loop_write(g.mosq, 1);
    if (rc != MOSQ_ERR_SUCCESS && g.st == ST_CONNECTING)
        log_info("sparkplug: %s:%d: %s", g.sc.host, g.sc.port,
                 rc == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(rc));
    after();
}

static struct spb_payload *ndeath_payload(int bd, uint64_t ts)
{
    struct spb_payload *pl = spb_payload_new(1);
    struct spb_payload_val v;
    memset(&v, 0, sizeof v);
    v.u = (uint64_t)bd;
    if (pl && spb_payload_add(pl, "bdSeq", 0, SPB_PAYLOAD_INT64, ts, &v) < 0) {
        spb_payload_free(pl);
        pl = NULL;
    }
    return pl;
}

static void try_connect(void *arg)
{
    int bd = g.next_bd, rc;
    uint64_t ts = now_ms();
    struct spb_payload *pl;
    uint8_t *buf;
    size_t len;
    (void)arg;
    g.retry_timer = 0;
    if (g.file_bd != bd) {
        if (bdseq_save(bd)) {
            log_err("sparkplug: cannot save the bdSeq in %s/%s: %s; not connecting", g.state_dir, BDSEQ_FILE,
                    strerror(errno));
            schedule_retry();
            return;
        }
        g.file_bd = bd;
    }
    pl = ndeath_payload(bd, ts);
    if (!pl || spb_payload_pack(pl, ts, -1, &buf, &len)) {
        spb_payload_free(pl);
        schedule_retry();
        return;
    }
    spb_payload_free(pl);
    /* The will is the NDEATH: QoS 1, not retained, only the bdSeq. */
    rc = mosquitto_will_set(g.mosq, g.t_ndeath, (int)len, buf, 1, false);
    free(buf);
    if (rc == MOSQ_ERR_SUCCESS)
        rc = mosquitto_connect_async(g.mosq, g.sc.host, g.sc.port, g.sc.keepalive);
    if (rc != MOSQ_ERR_SUCCESS) {
        /* No CONNECT went out: the next attempt takes the same bdSeq. */
        log_info("sparkplug: cannot connect to %s:%d: %s", g.sc.host, g.sc.port,
                 rc == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(rc));
        g.dropped = 0;
        schedule_retry();
        sync_fd();
        return;
    }
    g.bdseq = bd;
    g.next_bd = (bd + 1) & 255;
    g.st = ST_CONNECTING;
    g.host_on = 0; /* until its STATE (retained) says online */
    g.leaving = 0;
    g.dropped = 0;
    sync_fd();
}

/* libmosquitto's own errors (TLS: "certificate verify failed") into ours. */
static void on_log(struct mosquitto *m, void *obj, int level, const char *str)
{
    (void)m;
    (void)obj;
    if (level & (MOSQ_LOG_ERR | MOSQ_LOG_WARNING))
        log_warn("sparkplug: libmosquitto: %s", str);
}

static int no_password(char *buf, int size, int rwflag, void *u)
{
    (void)buf;
    (void)size;
    (void)rwflag;
    (void)u;
    return 0; /* encrypted keys are refused at load (spb_tls.c) */
}

static void on_connect(struct mosquitto *m, void *obj, int rc)
{
    (void)m;
    (void)obj;
    if (rc) {
        log_err("sparkplug: broker %s:%d refused the connection: %s", g.sc.host, g.sc.port,
                mosquitto_connack_string(rc));
        return; /* libmosquitto drops the socket: after() retries */
    }
    g.st = ST_ONLINE;
    g.backoff_ms = BACKOFF_FIRST_MS;
    log_notice("sparkplug: connected to %s:%d as %s, edge node %s/%s, bdSeq %d", g.sc.host, g.sc.port, g.client_id,
               g.sc.group_id, g.sc.edge_node_id, g.bdseq);
    /* Commands first (spec 5.4): a Rebirth asked right after the NBIRTH
     * is not missed. */
    rc = mosquitto_subscribe(g.mosq, NULL, g.t_ncmd, 1);
    if (rc == MOSQ_ERR_SUCCESS)
        rc = mosquitto_subscribe(g.mosq, NULL, g.t_dcmd_sub, 1);
    /* The primary host's STATE (retained): the births wait for it. */
    if (rc == MOSQ_ERR_SUCCESS && g.use_host)
        rc = mosquitto_subscribe(g.mosq, NULL, g.t_state, 1);
    if (rc != MOSQ_ERR_SUCCESS)
        log_warn("sparkplug: subscribe: %s", mosquitto_strerror(rc));
    births();
}

static void on_disconnect(struct mosquitto *m, void *obj, int rc)
{
    (void)m;
    (void)obj;
    (void)rc;
    g.dropped = 1;
}

static void on_publish(struct mosquitto *m, void *obj, int mid)
{
    (void)m;
    (void)obj;
    if (g.ndeath_mid && mid == g.ndeath_mid)
        g.ndeath_acked = 1;
}

/* A DCMD to model-N (spb_dcmd.c): the device reports in DDATA. */
static void on_dcmd(int id, const uint8_t *buf, size_t len)
{
    struct model *md = models_by_id(id);
    struct dev *d = dev_find(id);
    if (!md || !d) {
        log_warn("sparkplug: DCMD for model-%d: no such device", id);
        return;
    }
    spb_dcmd_apply(md, &d->q, &g.mbo, buf, len);
    d->dirty = 1;
}

/* spBv1.0/STATE/<primary_host_id> (Sparkplug 3.0): online: born (and the
 * stored history published); offline: NDEATH and DISCONNECT, then wait
 * for it on a new connection. Only an offline STATE is compared: it is
 * taken when its timestamp is >= that of the last online STATE
 * (tck-id-operational-behavior-edge-node-termination-host-offline) and
 * ignored when older: the late will of a host session already replaced
 * (...-host-offline-timestamp). An online STATE is always taken
 * (tck-id-operational-behavior-edge-node-birth-sequence-wait names no
 * timestamp): a host restarted with its clock behind the last offline
 * STATE is still the host. */
static void on_state(const uint8_t *buf, size_t len)
{
    int online;
    uint64_t ts;
    char why[128];
    if (spb_payload_state_parse(buf, len, &online, &ts, why, sizeof why)) {
        log_warn("sparkplug: STATE of %s refused: %s", g.sc.primary_host_id, why);
        return;
    }
    if (!online && ts < g.host_ts) {
        log_info("sparkplug: offline STATE of %s older than its last online STATE: ignored (a replaced session's "
                 "will)",
                 g.sc.primary_host_id);
        return;
    }
    if (online)
        g.host_ts = ts;
    if (online && !g.host_on) {
        g.host_on = 1;
        log_notice("sparkplug: primary host %s online", g.sc.primary_host_id);
        if (g.st == ST_ONLINE && g.need_birth)
            births();
    } else if (!online) {
        int was_born = g.host_on && !g.need_birth;
        g.host_on = 0;
        log_notice("sparkplug: primary host %s offline%s", g.sc.primary_host_id,
                   was_born ? ": NDEATH, disconnecting; changes are kept until it is back" : "; waiting for it");
        if (was_born && g.st == ST_ONLINE) {
            struct spb_payload *pl = ndeath_payload(g.bdseq, now_ms());
            /* Both queued in order: the broker has the NDEATH before the
             * DISCONNECT that discards the will. */
            if (pl)
                publish(g.t_ndeath, pl, now_ms(), -1, 1, NULL);
            spb_payload_free(pl);
            g.leaving = 1;
            g.need_birth = 1;
            mosquitto_disconnect(g.mosq);
        }
    }
}

static void on_message(struct mosquitto *m, void *obj, const struct mosquitto_message *msg)
{
    struct spb_payload_cmd cmd;
    char why[128];
    size_t pre = strlen(g.t_dpre[TP_DCMD]);
    (void)m;
    (void)obj;
    if (g.use_host && !strcmp(msg->topic, g.t_state)) {
        on_state(msg->payload, (size_t)(msg->payloadlen > 0 ? msg->payloadlen : 0));
        return;
    }
    if (!strncmp(msg->topic, g.t_dpre[TP_DCMD], pre)) {
        char *end;
        long id = strtol(msg->topic + pre, &end, 10);
        if (end == msg->topic + pre || *end || id < 0 || id > 254)
            log_warn("sparkplug: DCMD for %s: no such device", msg->topic);
        else if (g.st == ST_ONLINE)
            on_dcmd((int)id, msg->payload, (size_t)(msg->payloadlen > 0 ? msg->payloadlen : 0));
        return;
    }
    if (strcmp(msg->topic, g.t_ncmd))
        return;
    if (spb_payload_cmd_parse(msg->payload, (size_t)(msg->payloadlen > 0 ? msg->payloadlen : 0), NA_REBIRTH, &cmd, why,
                              sizeof why)) {
        log_warn("sparkplug: NCMD refused: %s", why);
        return;
    }
    if (!cmd.rebirth) {
        log_notice("sparkplug: NCMD with %d metric(s) and no Rebirth request: nothing to do", cmd.nmetrics);
        return;
    }
    log_info("sparkplug: NCMD Node Control/Rebirth");
    if (g.st == ST_ONLINE)
        births();
}

static void on_tick(void *arg)
{
    (void)arg;
    g.tick_timer = loop_add_timer(TICK_MS, on_tick, NULL);
    if (g.st == ST_IDLE) {
        if (g.sf_max && !models_pass_dirty())
            scan(1); /* stored: the moves without a durable change too */
        return;
    }
    mosquitto_loop_misc(g.mosq); /* keep-alive: PINGREQ, or drop a silent broker */
    after();
    /* What changed without a durable change (last_error, counters); not
     * while a change is on its way to the disk, so its DDATA carries the
     * request that made it too. */
    if (!models_pass_dirty())
        scan(1);
    sync_fd();
}

static void on_hook(void *arg)
{
    (void)arg;
    if (!g.on)
        return;
    scan(0);
    sync_fd();
}

/* ---- the module ---- */

static void opts_from(const struct conf *c)
{
    memset(&g.mbo, 0, sizeof g.mbo);
    g.mbo.word_order = IT2N_REGMAP_WO_ABCD;
    g.mbo.int32_order = IT2N_REGMAP_WO_ABCD;
    g.mbo.coord_scale = c->coord_scale;
    /* The Modbus grid size, so the register map's grid cache serves both. */
    g.mbo.grid_rows = (unsigned)c->grid_rows;
    g.mbo.grid_cols = (unsigned)c->grid_cols;
    for (int k = 0; k < c->nmodels; k++)
        if (c->model[k].write_protect)
            g.mbo.write_protect[c->model[k].unit / 8] |= (uint8_t)(1u << (c->model[k].unit % 8));
}

int spb_start(const struct conf *c, const char *version)
{
    const struct spb_conf *s = &c->spb;
    int rc;
    if (!s->enabled)
        return 0;
    g.sc = *s;
    snprintf(g.state_dir, sizeof g.state_dir, "%s", c->state_dir);
    snprintf(g.version, sizeof g.version, "%s", version);
    opts_from(c);
    if (s->client_id[0])
        snprintf(g.client_id, sizeof g.client_id, "%s", s->client_id);
    else
        snprintf(g.client_id, sizeof g.client_id, "it2nd-%s-%s", s->group_id, s->edge_node_id);
    snprintf(g.t_nbirth, sizeof g.t_nbirth, NS "/%s/NBIRTH/%s", s->group_id, s->edge_node_id);
    snprintf(g.t_ndeath, sizeof g.t_ndeath, NS "/%s/NDEATH/%s", s->group_id, s->edge_node_id);
    snprintf(g.t_ncmd, sizeof g.t_ncmd, NS "/%s/NCMD/%s", s->group_id, s->edge_node_id);
    snprintf(g.t_dpre[TP_DBIRTH], sizeof g.t_dpre[0], NS "/%s/DBIRTH/%s/model-", s->group_id, s->edge_node_id);
    snprintf(g.t_dpre[TP_DDATA], sizeof g.t_dpre[0], NS "/%s/DDATA/%s/model-", s->group_id, s->edge_node_id);
    snprintf(g.t_dpre[TP_DDEATH], sizeof g.t_dpre[0], NS "/%s/DDEATH/%s/model-", s->group_id, s->edge_node_id);
    snprintf(g.t_dpre[TP_DCMD], sizeof g.t_dpre[0], NS "/%s/DCMD/%s/model-", s->group_id, s->edge_node_id);
    snprintf(g.t_dcmd_sub, sizeof g.t_dcmd_sub, NS "/%s/DCMD/%s/+", s->group_id, s->edge_node_id);
    g.file_bd = bdseq_load();
    if (g.file_bd == -2)
        return -1;
    g.next_bd = g.file_bd < 0 ? 0 : (g.file_bd + 1) & 255;
    g.use_host = s->primary_host_id[0] != 0;
    g.host_on = !g.use_host;
    snprintf(g.t_state, sizeof g.t_state, NS "/STATE/%s", s->primary_host_id);
    g.sf_max = spb_conf_sf_max(s);
    if (g.sf_max) {
        int kept = spb_sf_open(g.state_dir, g.sf_max);
        if (kept < 0)
            return -1;
        if (kept)
            log_notice("sparkplug: %d stored change(s) in %s/%s wait for the host", kept, g.state_dir, SPB_SF_FILE);
        sf_base(); /* what the host will get in the births: the baseline */
    }
    mosquitto_lib_init();
    /* Clean session (spec: always true for Sparkplug clients). */
    g.mosq = mosquitto_new(g.client_id, true, NULL);
    if (!g.mosq) {
        log_err("sparkplug: cannot create the MQTT client: %s", strerror(errno));
        return -1;
    }
    mosquitto_int_option(g.mosq, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
    mosquitto_int_option(g.mosq, MOSQ_OPT_TCP_NODELAY, 1);
    if (s->username[0] && (rc = mosquitto_username_pw_set(g.mosq, s->username, s->password_set ? s->password : NULL)) !=
                              MOSQ_ERR_SUCCESS) {
        log_err("sparkplug: username: %s", mosquitto_strerror(rc));
        return -1;
    }
    if (s->tls_ca[0]) {
        /* Server verification: the chain against tls_ca and the host name
         * against `broker` (libmosquitto's default, not "insecure"). */
        rc = mosquitto_tls_set(g.mosq, s->tls_ca, NULL, s->tls_cert[0] ? s->tls_cert : NULL,
                               s->tls_key[0] ? s->tls_key : NULL, no_password);
        if (rc == MOSQ_ERR_SUCCESS)
            rc = mosquitto_tls_opts_set(g.mosq, 1, NULL, NULL);
        if (rc != MOSQ_ERR_SUCCESS) {
            log_err("sparkplug: TLS: %s", mosquitto_strerror(rc));
            return -1;
        }
    }
    mosquitto_log_callback_set(g.mosq, on_log);
    mosquitto_connect_callback_set(g.mosq, on_connect);
    mosquitto_disconnect_callback_set(g.mosq, on_disconnect);
    mosquitto_publish_callback_set(g.mosq, on_publish);
    mosquitto_message_callback_set(g.mosq, on_message);
    if (loop_add_hook(on_hook, NULL)) {
        log_err("sparkplug: no loop hook left");
        return -1;
    }
    g.on = 1;
    g.backoff_ms = BACKOFF_FIRST_MS;
    g.retry_timer = loop_add_timer(0, try_connect, NULL);
    g.tick_timer = loop_add_timer(TICK_MS, on_tick, NULL);
    log_info("sparkplug: edge node %s/%s, broker %s:%d, next bdSeq %d", s->group_id, s->edge_node_id, s->host, s->port,
             g.next_bd);
    if (g.use_host || g.sf_max)
        log_info("sparkplug: primary host %s, store-and-forward of at most %d change(s)",
                 g.use_host ? s->primary_host_id : "(none)", g.sf_max);
    return 0;
}

void spb_model_changed(int id)
{
    struct dev *d;
    if (!g.on || !(d = dev_find(id)))
        return;
    d->dirty = 1;
    loop_wake();
}

void spb_batch_done(void)
{
    if (!g.on)
        return;
    for (int k = 0; k < g.ndevs; k++)
        g.devs[k].dirty = 1;
}

void spb_reload(const struct conf *c)
{
    int changed = 0;
    if (!g.on) {
        if (c->spb.enabled)
            log_warn("reload: [sparkplug] added; takes effect at restart");
        return;
    }
    if (!spb_conf_same(&c->spb, &g.sc))
        log_warn("reload: [sparkplug] changes take effect at restart");
    if ((unsigned)c->grid_rows != g.mbo.grid_rows || (unsigned)c->grid_cols != g.mbo.grid_cols)
        changed = 1;
    opts_from(c);
    if (models_count() != g.ndevs)
        changed = 1;
    for (int k = 0; k < g.ndevs; k++) {
        if (models_by_id(g.devs[k].id))
            continue;
        changed = 1;
        if (g.st == ST_ONLINE) {
            /* The model is gone: its device dies (spec 4.4.4). */
            struct spb_payload *pl = spb_payload_new(1);
            char topic[200];
            dev_topic(topic, sizeof topic, TP_DDEATH, g.devs[k].id);
            if (pl)
                publish_seq(topic, pl, now_ms());
            spb_payload_free(pl);
        }
    }
    for (int k = 0; k < models_count(); k++)
        if (!dev_find(models_at(k)->id))
            changed = 1;
    if (!changed)
        return;
    if (g.st == ST_ONLINE)
        births(); /* the metric set changed: born again with it */
    else if (devs_build())
        log_err("sparkplug: out of memory building the device table");
    sync_fd();
}

/* Run libmosquitto on its socket alone until done() or ms pass (stop). */
static void wait_for(int (*done)(void), int ms)
{
    uint64_t end = loop_now_ms() + (uint64_t)ms;
    while (!done() && mosquitto_socket(g.mosq) >= 0) {
        uint64_t now = loop_now_ms();
        struct pollfd p;
        if (now >= end)
            return;
        p.fd = mosquitto_socket(g.mosq);
        p.events = (short)(POLLIN | (mosquitto_want_write(g.mosq) ? POLLOUT : 0));
        p.revents = 0;
        if (poll(&p, 1, (int)(end - now)) < 0 && errno != EINTR)
            return;
        if (p.revents & (POLLIN | POLLERR | POLLHUP))
            mosquitto_loop_read(g.mosq, 1);
        if ((p.revents & POLLOUT) && mosquitto_socket(g.mosq) >= 0)
            mosquitto_loop_write(g.mosq, 1);
    }
}

static int ndeath_done(void)
{
    return g.ndeath_acked;
}

static int flushed(void)
{
    return !mosquitto_want_write(g.mosq);
}

void spb_stop(void)
{
    if (!g.on)
        return;
    if (g.retry_timer)
        loop_cancel_timer(g.retry_timer);
    if (g.tick_timer)
        loop_cancel_timer(g.tick_timer);
    g.retry_timer = g.tick_timer = 0;
    if (g.st != ST_ONLINE && g.sf_max)
        scan(0); /* changes made durable by the last drain: kept */
    if (g.st == ST_ONLINE) {
        uint64_t ts = now_ms();
        struct spb_payload *pl = ndeath_payload(g.bdseq, ts);
        wait_for(flushed, STOP_WAIT_MS / 2);
        scan(0); /* changes made durable by the last drain */
        g.ndeath_mid = 0;
        g.ndeath_acked = 0;
        if (pl && publish(g.t_ndeath, pl, ts, -1, 1, &g.ndeath_mid) == 0) {
            wait_for(ndeath_done, STOP_WAIT_MS);
            if (g.ndeath_acked)
                log_info("sparkplug: NDEATH published (bdSeq %d)", g.bdseq);
            else
                log_warn("sparkplug: NDEATH not acknowledged by the broker within %d ms; the will follows",
                         STOP_WAIT_MS);
        }
        spb_payload_free(pl);
        if (g.ndeath_acked) {
            /* DISCONNECT only after the NDEATH is the broker's: a DISCONNECT
             * discards the will, so a lost NDEATH would leave no death. */
            mosquitto_disconnect(g.mosq);
            wait_for(flushed, STOP_WAIT_MS / 2);
        }
    }
    if (g.fd >= 0)
        loop_del_fd(g.fd);
    g.fd = -1;
    mosquitto_destroy(g.mosq);
    mosquitto_lib_cleanup();
    spb_sf_close();
    g.mosq = NULL;
    devs_free();
    g.on = 0;
    g.st = ST_IDLE;
}
