/*
 * ctl_spb.c — it2nctl as a Sparkplug B host application (docs/sparkplug.md,
 * "Watching without a SCADA"): `it2nctl spb watch` prints the births and
 * deaths of a group's edge nodes and devices, and the generations of the
 * models, one CSV line per event; `it2nctl spb status|eval` are it2nctl's
 * status and eval through a device's DCMD query (a transport, ctl_ops, so
 * the output is exactly that of the other transports). MQTT by libmosquitto
 * (synchronous: a command-line tool waits anyway), payloads by the
 * protobuf-c code generated from daemon/spb.proto.
 */
#include "ctl.h"

#include <errno.h>
#include <math.h>
#include <mosquitto.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "spb.pb-c.h"

#define NS "spBv1.0"
#define T_FLOAT 9u
#define T_BOOLEAN 11u
#define T_INT16 2u
#define T_INT32 3u

static uint64_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static uint64_t mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

/* HOST:PORT (or [V6]:PORT, or HOST: port 1883) into host and port. */
static const char *split_broker(const char *b, char *host, size_t hn, int *port)
{
    char ps[16];
    const char *bad = ctl_tcp_split(b, host, hn, ps, sizeof(ps));
    if (bad != NULL) {
        return bad;
    }
    /* ctl_tcp_split defaults to Modbus's 1502: MQTT's is 1883. */
    *port = strchr(b, ']') ? (strrchr(b, ':') > strchr(b, ']') ? atoi(ps) : 1883) : (strchr(b, ':') ? atoi(ps) : 1883);
    return NULL;
}

/* A connected client, or NULL (the reason printed, *rc = CTL_EXIT_COMM). */
static struct mosquitto *connect_broker(const char *broker, const char *what, void *obj, int *rc)
{
    char host[256], cid[64];
    int port = 1883, r;
    struct mosquitto *m;
    const char *bad = split_broker(broker, host, sizeof(host), &port);
    if (bad != NULL) {
        fprintf(stderr, "it2nctl: --broker '%s': %s\n", broker, bad);
        *rc = CTL_EXIT_USAGE;
        return NULL;
    }
    mosquitto_lib_init();
    snprintf(cid, sizeof(cid), "it2nctl-%s-%ld-%lu", what, (long)getpid(), (unsigned long)(now_ms() % 1000000u));
    m = mosquitto_new(cid, true, obj);
    if (m == NULL) {
        fprintf(stderr, "it2nctl: out of memory\n");
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    mosquitto_int_option(m, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
    r = mosquitto_connect(m, host, port, 30);
    if (r != MOSQ_ERR_SUCCESS) {
        fprintf(stderr, "it2nctl: broker %s: %s\n", broker,
                r == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(r));
        mosquitto_destroy(m);
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    return m;
}

/* An NCMD Node Control/Rebirth = true (a host that has no birth of a node
 * asks for one, as a Sparkplug host does). */
static void ask_rebirth(struct mosquitto *m, const char *group, const char *node)
{
    Spb__Payload p = SPB__PAYLOAD__INIT;
    Spb__Payload__Metric mt = SPB__PAYLOAD__METRIC__INIT;
    Spb__Payload__Metric *mp = &mt;
    char topic[300];
    uint8_t buf[128];
    size_t len;
    mt.name = (char *)"Node Control/Rebirth";
    mt.has_datatype = 1;
    mt.datatype = T_BOOLEAN;
    mt.has_timestamp = 1;
    mt.timestamp = now_ms();
    mt.value_case = SPB__PAYLOAD__METRIC__VALUE_BOOLEAN_VALUE;
    mt.boolean_value = 1;
    p.has_timestamp = 1;
    p.timestamp = mt.timestamp;
    p.n_metrics = 1;
    p.metrics = &mp;
    len = spb__payload__pack(&p, buf);
    snprintf(topic, sizeof(topic), NS "/%s/NCMD/%s", group, node);
    mosquitto_publish(m, NULL, topic, (int)len, buf, 1, false);
}

static int64_t int_value(const Spb__Payload__Metric *mt, uint32_t type)
{
    if (mt->value_case == SPB__PAYLOAD__METRIC__VALUE_LONG_VALUE) {
        return (int64_t)mt->long_value;
    }
    if (type == T_INT16 || type == T_INT32) {
        return (int32_t)mt->int_value;
    }
    return mt->int_value;
}

/* ---- watch -------------------------------------------------------------- */

typedef struct w_dev {
    char node[64], dev[64];
    int online;
    uint64_t a_gen, a_state; /* aliases of Status/generation, Status/state */
    int64_t gen, state;
} w_dev;

typedef struct w_node {
    char node[64];
    int online, asked;
    int64_t bdseq;
} w_node;

typedef struct watch {
    const char *group, *node;
    w_node *nodes;
    size_t nn;
    w_dev *devs;
    size_t nd;
    unsigned count, lines;
    int oom;
} watch;

static w_node *w_node_get(watch *w, const char *node)
{
    w_node *n;
    for (size_t k = 0; k < w->nn; k++) {
        if (strcmp(w->nodes[k].node, node) == 0) {
            return &w->nodes[k];
        }
    }
    n = realloc(w->nodes, (w->nn + 1u) * sizeof(*n));
    if (n == NULL) {
        w->oom = 1;
        return NULL;
    }
    w->nodes = n;
    n = &w->nodes[w->nn++];
    memset(n, 0, sizeof(*n));
    snprintf(n->node, sizeof(n->node), "%s", node);
    n->bdseq = -1;
    return n;
}

static w_dev *w_dev_get(watch *w, const char *node, const char *dev)
{
    w_dev *d;
    for (size_t k = 0; k < w->nd; k++) {
        if (strcmp(w->devs[k].node, node) == 0 && strcmp(w->devs[k].dev, dev) == 0) {
            return &w->devs[k];
        }
    }
    d = realloc(w->devs, (w->nd + 1u) * sizeof(*d));
    if (d == NULL) {
        w->oom = 1;
        return NULL;
    }
    w->devs = d;
    d = &w->devs[w->nd++];
    memset(d, 0, sizeof(*d));
    snprintf(d->node, sizeof(d->node), "%s", node);
    snprintf(d->dev, sizeof(d->dev), "%s", dev);
    d->gen = d->state = -1;
    return d;
}

static void put_num(int64_t v)
{
    if (v >= 0) {
        printf("%lld", (long long)v);
    }
}

static void w_line(watch *w, const char *node, const char *dev, const char *event, int64_t bdseq, int64_t gen,
                   int64_t state)
{
    uint64_t ms = now_ms();
    time_t t = (time_t)(ms / 1000u);
    struct tm tm;
    char ts[32];
    gmtime_r(&t, &tm);
    strftime(ts, sizeof(ts), "%Y-%m-%dT%H:%M:%S", &tm);
    printf("%s.%03uZ,%s,%s,%s,", ts, (unsigned)(ms % 1000u), node, dev ? dev : "", event);
    put_num(bdseq);
    putchar(',');
    put_num(gen);
    printf(",%s\n", state >= 0 ? ctl_state_name((int)state) : "");
    fflush(stdout);
    w->lines++;
}

static void w_dev_values(w_dev *d, const Spb__Payload *p, int birth)
{
    for (size_t k = 0; k < p->n_metrics; k++) {
        const Spb__Payload__Metric *mt = p->metrics[k];
        if (birth && mt->name != NULL && mt->has_alias) {
            if (strcmp(mt->name, "Status/generation") == 0) {
                d->a_gen = mt->alias;
            } else if (strcmp(mt->name, "Status/state") == 0) {
                d->a_state = mt->alias;
            }
        }
        if (mt->has_is_null && mt->is_null) {
            continue;
        }
        if ((mt->name && strcmp(mt->name, "Status/generation") == 0) ||
            (!mt->name && mt->has_alias && d->a_gen && mt->alias == d->a_gen)) {
            d->gen = int_value(mt, 7u);
        } else if ((mt->name && strcmp(mt->name, "Status/state") == 0) ||
                   (!mt->name && mt->has_alias && d->a_state && mt->alias == d->a_state)) {
            d->state = int_value(mt, 6u);
        }
    }
}

/* The bdSeq metric of an NBIRTH or NDEATH, -1 without one. */
static int64_t payload_bdseq(const Spb__Payload *p)
{
    int64_t bd = -1;
    for (size_t k = 0; k < p->n_metrics; k++) {
        if (p->metrics[k]->name && strcmp(p->metrics[k]->name, "bdSeq") == 0) {
            bd = int_value(p->metrics[k], 4u);
        }
    }
    return bd;
}

static void w_node_birth(watch *w, w_node *n, const Spb__Payload *p)
{
    int64_t bd = payload_bdseq(p);
    /* A Rebirth keeps the session (its bdSeq): said once, as such. */
    w_line(w, n->node, NULL, n->online && bd == n->bdseq ? "rebirth" : "online", bd, -1, -1);
    if (!n->online || bd != n->bdseq) {
        for (size_t k = 0; k < w->nd; k++) {
            if (strcmp(w->devs[k].node, n->node) == 0) {
                w->devs[k].online = 0; /* born again in the DBIRTHs */
            }
        }
    }
    n->bdseq = bd;
    n->online = 1;
}

static void w_node_death(watch *w, w_node *n, const Spb__Payload *p)
{
    int64_t bd = payload_bdseq(p);
    /* The will of an older session (another bdSeq) says nothing of
     * this one (spec: a host compares the bdSeq). */
    if (n->online && bd == n->bdseq) {
        n->online = 0;
        for (size_t k = 0; k < w->nd; k++) {
            w_dev *d = &w->devs[k];
            if (d->online && strcmp(d->node, n->node) == 0) {
                d->online = 0;
                w_line(w, n->node, d->dev, "offline", bd, d->gen, d->state);
            }
        }
        w_line(w, n->node, NULL, "offline", bd, -1, -1);
    }
}

/* DBIRTH, DDATA or DDEATH (type) of device dev of node n. */
static void w_device(struct mosquitto *m, watch *w, w_node *n, const char *type, const char *dev, const Spb__Payload *p)
{
    w_dev *d = w_dev_get(w, n->node, dev);
    if (d == NULL) {
        return;
    }
    if (type[1] == 'B') {
        int64_t gen = d->gen, st = d->state;
        int was = d->online;
        d->online = 1;
        d->a_gen = d->a_state = 0;
        w_dev_values(d, p, 1);
        if (!was) {
            w_line(w, n->node, d->dev, "online", n->bdseq, d->gen, d->state);
        } else if (d->gen != gen || d->state != st) {
            w_line(w, n->node, d->dev, "generation", n->bdseq, d->gen, d->state);
        }
    } else if (type[1] == 'D' && type[2] == 'A') {
        int64_t gen = d->gen, st = d->state;
        if (!d->online || !n->online) {
            /* Data of a session this host has no birth of: ask. */
            if (!n->asked) {
                ask_rebirth(m, w->group, n->node);
                n->asked = 1;
            }
        } else {
            w_dev_values(d, p, 0);
            if (d->gen != gen || d->state != st) {
                w_line(w, n->node, d->dev, "generation", n->bdseq, d->gen, d->state);
            }
        }
    } else if (d->online) {
        d->online = 0;
        w_line(w, n->node, d->dev, "offline", n->bdseq, d->gen, d->state);
    }
}

static void w_message(struct mosquitto *m, void *obj, const struct mosquitto_message *msg)
{
    watch *w = obj;
    char buf[512], *part[6], *save = NULL;
    int np = 0;
    Spb__Payload *p;
    w_node *n;
    snprintf(buf, sizeof(buf), "%s", msg->topic);
    for (char *s = strtok_r(buf, "/", &save); s && np < 6; s = strtok_r(NULL, "/", &save)) {
        part[np++] = s;
    }
    if (np < 4 || strcmp(part[0], NS) != 0 || strcmp(part[2], "STATE") == 0 ||
        (w->node && strcmp(part[3], w->node) != 0) || (w->count && w->lines >= w->count)) {
        return;
    }
    if (strcmp(part[2], "NCMD") == 0 || strcmp(part[2], "DCMD") == 0) {
        return;
    }
    p = spb__payload__unpack(NULL, (size_t)(msg->payloadlen > 0 ? msg->payloadlen : 0), msg->payload);
    if (p == NULL) {
        fprintf(stderr, "it2nctl: %s: not a Sparkplug B payload (ignored)\n", msg->topic);
        return;
    }
    n = w_node_get(w, part[3]);
    if (n == NULL) {
        spb__payload__free_unpacked(p, NULL);
        return;
    }
    if (strcmp(part[2], "NBIRTH") == 0) {
        w_node_birth(w, n, p);
    } else if (strcmp(part[2], "NDEATH") == 0) {
        w_node_death(w, n, p);
    } else if (np >= 5 &&
               (strcmp(part[2], "DBIRTH") == 0 || strcmp(part[2], "DDATA") == 0 || strcmp(part[2], "DDEATH") == 0)) {
        w_device(m, w, n, part[2], part[4], p);
    } else if (strcmp(part[2], "NDATA") == 0 && !n->online && !n->asked) {
        ask_rebirth(m, w->group, n->node);
        n->asked = 1;
    }
    spb__payload__free_unpacked(p, NULL);
}

static const char watch_help[] = "Usage: it2nctl spb watch --broker HOST:PORT --group G [--node N] [--count N]\n"
                                 "Watch a Sparkplug B group as a host application: one CSV line per event,\n"
                                 "time,node,device,event,bdseq,generation,state\n"
                                 "  event  online, offline (node: NBIRTH, NDEATH of its session; device:\n"
                                 "         DBIRTH, DDEATH, or its node's death), rebirth (a node's NBIRTH\n"
                                 "         in the same session: a Rebirth), generation (a device's model\n"
                                 "         changed generation or state).\n"
                                 "With --node, the node is asked for a Rebirth at once, so its current\n"
                                 "state is printed; without, a node is asked when data of it comes before\n"
                                 "its birth.\n"
                                 "  --broker HOST:PORT   the MQTT broker (port 1883 when left out)\n"
                                 "  --group G            Sparkplug group_id\n"
                                 "  --node N             only this edge_node_id\n"
                                 "  --count N            stop after N lines (default: until interrupted)\n"
                                 "Exit status: 0 ok, 1 usage error, 3 broker unreachable or lost.\n";

int ctl_spb_watch(int argc, char **argv)
{
    watch w;
    const char *broker = NULL;
    struct mosquitto *m;
    char topic[200];
    int rc = CTL_EXIT_OK, k;
    memset(&w, 0, sizeof(w));
    for (k = 1; k < argc; k++) {
        const char *o = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (strcmp(o, "--help") == 0 || strcmp(o, "-h") == 0) {
            fputs(watch_help, stdout);
            return CTL_EXIT_OK;
        }
        if (strcmp(o, "--broker") && strcmp(o, "--group") && strcmp(o, "--node") && strcmp(o, "--count")) {
            fprintf(stderr, "it2nctl: spb watch: unknown option '%s'\nTry 'it2nctl spb watch --help'.\n", o);
            return CTL_EXIT_USAGE;
        }
        if (v == NULL) {
            fprintf(stderr, "it2nctl: spb watch: option '%s' needs an argument\n", o);
            return CTL_EXIT_USAGE;
        }
        k++;
        if (strcmp(o, "--broker") == 0) {
            broker = v;
        } else if (strcmp(o, "--group") == 0) {
            w.group = v;
        } else if (strcmp(o, "--node") == 0) {
            w.node = v;
        } else {
            char *end;
            unsigned long c = strtoul(v, &end, 10);
            if (*v < '0' || *v > '9' || *end || c < 1 || c > 1000000000ul) {
                fprintf(stderr, "it2nctl: spb watch: --count '%s': expected 1 or more\n", v);
                return CTL_EXIT_USAGE;
            }
            w.count = (unsigned)c;
        }
    }
    if (broker == NULL || w.group == NULL) {
        fprintf(stderr, "it2nctl: spb watch needs --broker HOST:PORT and --group G\n"
                        "Try 'it2nctl spb watch --help'.\n");
        return CTL_EXIT_USAGE;
    }
    if (strpbrk(w.group, "/+#") || (w.node && strpbrk(w.node, "/+#"))) {
        fprintf(stderr, "it2nctl: spb watch: a group or node id is one topic level (no '/', '+', '#')\n");
        return CTL_EXIT_USAGE;
    }
    m = connect_broker(broker, "watch", &w, &rc);
    if (m == NULL) {
        return rc;
    }
    mosquitto_message_callback_set(m, w_message);
    if (w.node) {
        snprintf(topic, sizeof(topic), NS "/%s/+/%s/#", w.group, w.node);
    } else {
        snprintf(topic, sizeof(topic), NS "/%s/#", w.group);
    }
    mosquitto_subscribe(m, NULL, topic, 1);
    printf("time,node,device,event,bdseq,generation,state\n");
    fflush(stdout);
    if (w.node) {
        w_node_get(&w, w.node)->asked = 1;
        ask_rebirth(m, w.group, w.node);
    }
    while (!w.count || w.lines < w.count) {
        int r = mosquitto_loop(m, 1000, 1);
        if (w.oom) {
            fprintf(stderr, "it2nctl: out of memory\n");
            rc = CTL_EXIT_COMM;
            break;
        }
        if (r != MOSQ_ERR_SUCCESS) {
            fprintf(stderr, "it2nctl: broker %s: connection lost: %s\n", broker,
                    r == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(r));
            rc = CTL_EXIT_COMM;
            break;
        }
    }
    mosquitto_disconnect(m);
    mosquitto_destroy(m);
    mosquitto_lib_cleanup();
    free(w.nodes);
    free(w.devs);
    return rc;
}

/* ---- status and eval through DCMD (a transport) ------------------------- */

typedef struct s_met {
    char *name;
    uint64_t alias;
    uint32_t type;
    int null;
    int64_t i;
    float f;
} s_met;

typedef struct spb_conn {
    struct mosquitto *m;
    const char *broker;
    char t_dbirth[300], t_ddata[300], t_ddeath[300], t_ndeath[300], t_dcmd[300];
    const char *group, *node;
    unsigned model, timeout_ms;
    int born, died;
    s_met *met;
    size_t nmet;
    int oom;
} spb_conn;

static void met_free(spb_conn *c)
{
    for (size_t k = 0; k < c->nmet; k++) {
        free(c->met[k].name);
    }
    free(c->met);
    c->met = NULL;
    c->nmet = 0;
}

static void met_set(s_met *s, const Spb__Payload__Metric *mt)
{
    s->null = mt->has_is_null && mt->is_null;
    if (s->null) {
        return;
    }
    if (mt->value_case == SPB__PAYLOAD__METRIC__VALUE_FLOAT_VALUE) {
        s->f = mt->float_value;
    } else {
        s->i = int_value(mt, s->type);
    }
}

static void c_message(struct mosquitto *m, void *obj, const struct mosquitto_message *msg)
{
    spb_conn *c = obj;
    Spb__Payload *p;
    (void)m;
    if (strcmp(msg->topic, c->t_ddeath) == 0 || strcmp(msg->topic, c->t_ndeath) == 0) {
        c->died = c->born;
        c->born = 0;
        return;
    }
    p = spb__payload__unpack(NULL, (size_t)(msg->payloadlen > 0 ? msg->payloadlen : 0), msg->payload);
    if (p == NULL) {
        return;
    }
    if (strcmp(msg->topic, c->t_dbirth) == 0) {
        met_free(c);
        c->met = calloc(p->n_metrics ? p->n_metrics : 1u, sizeof(*c->met));
        if (c->met == NULL) {
            c->oom = 1;
        }
        for (size_t k = 0; c->met && k < p->n_metrics; k++) {
            const Spb__Payload__Metric *mt = p->metrics[k];
            s_met *s = &c->met[c->nmet];
            if (mt->name == NULL || !(s->name = strdup(mt->name))) {
                continue;
            }
            s->alias = mt->alias;
            s->type = mt->datatype;
            met_set(s, mt);
            c->nmet++;
        }
        c->born = 1;
    } else if (strcmp(msg->topic, c->t_ddata) == 0 && c->born) {
        for (size_t k = 0; k < p->n_metrics; k++) {
            const Spb__Payload__Metric *mt = p->metrics[k];
            if (mt->has_is_historical && mt->is_historical) {
                continue; /* the past: the birth has the present */
            }
            for (size_t j = 0; j < c->nmet; j++) {
                if ((mt->name && strcmp(mt->name, c->met[j].name) == 0) ||
                    (!mt->name && mt->has_alias && mt->alias == c->met[j].alias)) {
                    met_set(&c->met[j], mt);
                    break;
                }
            }
        }
    }
    spb__payload__free_unpacked(p, NULL);
}

static const s_met *met(const spb_conn *c, const char *name)
{
    for (size_t k = 0; k < c->nmet; k++) {
        if (strcmp(c->met[k].name, name) == 0) {
            return &c->met[k];
        }
    }
    return NULL;
}

static int64_t met_i(const spb_conn *c, const char *name)
{
    const s_met *s = met(c, name);
    return s && !s->null ? s->i : 0;
}

/* Run the client until done(c) or the timeout; CTL_EXIT_COMM with a
 * message on a timeout or a lost connection. */
static int run_until(spb_conn *c, int (*done)(const spb_conn *, const void *), const void *arg, const char *what)
{
    uint64_t end = mono_ms() + c->timeout_ms;
    while (!done(c, arg)) {
        uint64_t now = mono_ms();
        int r;
        if (c->oom) {
            fprintf(stderr, "it2nctl: out of memory\n");
            return CTL_EXIT_COMM;
        }
        if (now >= end) {
            fprintf(stderr, "it2nctl: %s/%s model-%u: no %s within %u ms\n", c->group, c->node, c->model, what,
                    c->timeout_ms);
            return CTL_EXIT_COMM;
        }
        r = mosquitto_loop(c->m, (int)(end - now < 100 ? end - now : 100), 1);
        if (r != MOSQ_ERR_SUCCESS) {
            fprintf(stderr, "it2nctl: broker %s: %s\n", c->broker,
                    r == MOSQ_ERR_ERRNO ? strerror(errno) : mosquitto_strerror(r));
            return CTL_EXIT_COMM;
        }
    }
    return CTL_EXIT_OK;
}

static int is_born(const spb_conn *c, const void *arg)
{
    (void)arg;
    return c->born;
}

static int c_status(void *p, ctl_status *st)
{
    spb_conn *c = p;
    int rc = run_until(c, is_born, NULL, "DBIRTH (is the node online, the device configured?)");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    memset(st, 0, sizeof(*st));
    st->model = (unsigned)met_i(c, "Status/model_id");
    st->state = (int)met_i(c, "Status/state");
    st->n = (unsigned)met_i(c, "Status/n");
    st->m = (unsigned)met_i(c, "Status/m");
    st->flags = (unsigned)met_i(c, "Status/flags");
    st->present = (unsigned)met_i(c, "Status/points_present");
    st->required = (unsigned)met_i(c, "Status/points_required");
    st->generation = (uint32_t)met_i(c, "Status/generation");
    st->last_error = (int)met_i(c, "Status/last_error");
    return CTL_EXIT_OK;
}

typedef struct q_want {
    float u, w;
} q_want;

/* The device's query is (u, w) and its results are of the current
 * generation (the DDATA after the DCMD, or already so). */
static int answered(const spb_conn *c, const void *arg)
{
    const q_want *q = arg;
    const s_met *u = met(c, "Query/u"), *w = met(c, "Query/w"), *g = met(c, "Query/generation");
    const s_met *r = met(c, "Query/Result/D/T");
    return c->died || (u && w && g && r && !u->null && !w->null && !g->null && !r->null &&
                       memcmp(&u->f, &q->u, sizeof(float)) == 0 && memcmp(&w->f, &q->w, sizeof(float)) == 0 &&
                       g->i == met_i(c, "Status/generation"));
}

static it2n_val f2q(float f)
{
    double d = (double)f * (double)IT2N_VAL_ONE;
    if (!(d > -9.0e18 && d < 9.0e18)) {
        return d < 0 ? INT64_MIN >> 1 : INT64_MAX >> 1;
    }
    return (it2n_val)llround(d);
}

static int c_eval(void *p, it2n_par *u, it2n_par *w, it2n_point *pt)
{
    static const char *const fps[IT2N_FP_COUNT] = {"LL", "LR", "L", "D", "R", "RL", "RR"};
    static const char *const chs[IT2N_CH_COUNT] = {"x", "y", "z", "T", "I", "F"};
    static const char *const sums[4] = {"upper_min", "upper_max", "lower_min", "lower_max"};
    spb_conn *c = p;
    q_want q;
    Spb__Payload pl = SPB__PAYLOAD__INIT;
    Spb__Payload__Metric mt[2] = {SPB__PAYLOAD__METRIC__INIT, SPB__PAYLOAD__METRIC__INIT};
    Spb__Payload__Metric *mp[2] = {&mt[0], &mt[1]};
    it2n_point tmp;
    uint8_t buf[128];
    size_t len;
    char name[64];
    int rc;
    /* Query/u, Query/w are Float: the daemon evaluates at llround(f * 2^32),
     * as for the float32 query registers. */
    q.u = (float)((double)*u / (double)IT2N_PAR_ONE);
    q.w = (float)((double)*w / (double)IT2N_PAR_ONE);
    for (int k = 0; k < 2; k++) {
        mt[k].name = (char *)(k ? "Query/w" : "Query/u");
        mt[k].has_datatype = 1;
        mt[k].datatype = T_FLOAT;
        mt[k].has_timestamp = 1;
        mt[k].timestamp = now_ms();
        mt[k].value_case = SPB__PAYLOAD__METRIC__VALUE_FLOAT_VALUE;
        mt[k].float_value = k ? q.w : q.u;
    }
    pl.has_timestamp = 1;
    pl.timestamp = now_ms();
    pl.n_metrics = 2;
    pl.metrics = mp;
    len = spb__payload__pack(&pl, buf);
    mosquitto_publish(c->m, NULL, c->t_dcmd, (int)len, buf, 1, false);
    rc = run_until(c, answered, &q, "query answer (DDATA)");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (c->died) {
        fprintf(stderr, "it2nctl: %s/%s model-%u: the device died (DDEATH or NDEATH) before answering\n", c->group,
                c->node, c->model);
        return CTL_EXIT_COMM;
    }
    *u = (it2n_par)llround((double)q.u * (double)IT2N_PAR_ONE);
    *w = (it2n_par)llround((double)q.w * (double)IT2N_PAR_ONE);
    memset(pt, 0, sizeof(*pt));
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
            const s_met *s;
            snprintf(name, sizeof(name), "Query/Result/%s/%s", fps[fp], chs[ch]);
            s = met(c, name);
            pt->v[fp][ch] = s && !s->null ? f2q(s->f) : 0;
        }
    }
    for (unsigned k = 0; k < 3u; k++) {
        it2n_val *dst[4] = {&pt->sum.upper_min[k], &pt->sum.upper_max[k], &pt->sum.lower_min[k], &pt->sum.lower_max[k]};
        for (unsigned s_ = 0; s_ < 4u; s_++) {
            const s_met *s;
            snprintf(name, sizeof(name), "Query/Summary/%s/%s", sums[s_], chs[IT2N_CH_T + k]);
            s = met(c, name);
            *dst[s_] = s && !s->null ? f2q(s->f) : 0;
        }
    }
    /* No out-of-range metric: the bits from the values, as the core sets them. */
    tmp = *pt;
    ctl_summarise((met_i(c, "Status/flags") & IT2N_F_TYPE1) != 0, &tmp);
    pt->out_of_range = tmp.out_of_range;
    return CTL_EXIT_OK;
}

static int c_none(const char *what)
{
    fprintf(stderr, "it2nctl: %s is not available through Sparkplug (use --tcp, --rtu or --link)\n", what);
    return CTL_EXIT_USAGE;
}

static int c_push(void *c, const cli_data *src, ctl_progress_fn progress, void *pctx, it2n_errinfo *rej)
{
    (void)c;
    (void)src;
    (void)progress;
    (void)pctx;
    (void)rej;
    return c_none("push");
}

static int c_locate(void *c, it2n_val *x, it2n_val *y, ctl_loc res[IT2N_FP_COUNT])
{
    (void)c;
    (void)x;
    (void)y;
    (void)res;
    return c_none("locate");
}

static int c_net(void *c, const ctl_status *st, ctl_net *net)
{
    (void)c;
    (void)st;
    (void)net;
    return c_none("net");
}

static int c_sample(void *c, const ctl_status *st, unsigned rows, unsigned cols, ctl_sample_fn cb, void *ctx)
{
    (void)c;
    (void)st;
    (void)rows;
    (void)cols;
    (void)cb;
    (void)ctx;
    return c_none("sample");
}

static int c_wait(void *c, uint32_t gen, int timeout_ms, ctl_status *st)
{
    (void)c;
    (void)gen;
    (void)timeout_ms;
    (void)st;
    return c_none("watch (use 'it2nctl spb watch')");
}

static void c_close(void *p)
{
    spb_conn *c = p;
    mosquitto_disconnect(c->m);
    mosquitto_destroy(c->m);
    mosquitto_lib_cleanup();
    met_free(c);
    free(c);
}

static int c_coef_row(void *c, const ctl_status *st, unsigned fp, unsigned ch, unsigned row, it2n_val *out)
{
    (void)c;
    (void)st;
    (void)fp;
    (void)ch;
    (void)row;
    (void)out;
    return c_none("net");
}

static const ctl_ops spb_ops = {"sparkplug", c_status, c_push, c_eval,  c_locate,
                                c_net,       c_sample, c_wait, c_close, c_coef_row};

void *ctl_spb_open(const ctl_conn_opts *o, const ctl_ops **ops, int *rc)
{
    spb_conn *c = calloc(1, sizeof(*c));
    char topic[300];
    if (c == NULL) {
        fprintf(stderr, "it2nctl: out of memory\n");
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    c->broker = o->broker;
    c->group = o->group;
    c->node = o->node;
    c->model = o->model;
    c->timeout_ms = o->timeout_ms;
    snprintf(c->t_dbirth, sizeof(c->t_dbirth), NS "/%s/DBIRTH/%s/model-%u", c->group, c->node, c->model);
    snprintf(c->t_ddata, sizeof(c->t_ddata), NS "/%s/DDATA/%s/model-%u", c->group, c->node, c->model);
    snprintf(c->t_ddeath, sizeof(c->t_ddeath), NS "/%s/DDEATH/%s/model-%u", c->group, c->node, c->model);
    snprintf(c->t_dcmd, sizeof(c->t_dcmd), NS "/%s/DCMD/%s/model-%u", c->group, c->node, c->model);
    snprintf(c->t_ndeath, sizeof(c->t_ndeath), NS "/%s/NDEATH/%s", c->group, c->node);
    c->m = connect_broker(o->broker, "spb", c, rc);
    if (c->m == NULL) {
        free(c);
        return NULL;
    }
    mosquitto_message_callback_set(c->m, c_message);
    snprintf(topic, sizeof(topic), NS "/%s/+/%s/model-%u", c->group, c->node, c->model);
    mosquitto_subscribe(c->m, NULL, topic, 1);
    mosquitto_subscribe(c->m, NULL, c->t_ndeath, 1);
    /* The device's metrics (names, aliases, values) come in its DBIRTH:
     * ask the node for a new birth sequence, as a late-joining host does. */
    ask_rebirth(c->m, c->group, c->node);
    *ops = &spb_ops;
    return c;
}
