/* conf.c — see conf.h. */
#include "conf.h"

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <netdb.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>
#include <ini.h>
#include <pwd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "acl.h"
#include "it2n.h"
#include "it2n_regmap.h"

/* Where a section's settings came from, for cross-key errors. */
struct origin {
    int first_line;           /* its first key */
    char first_key[CONF_NAME];
    int unit_line, preload_line, removed_line;
    int n_line, m_line, kind_line, chord_line; /* [model:] keys checked against kind */
};

/* Where an [rtu:] section's RS-485 options are, for the checks between
 * them (an option without rs485 = yes, a kernel option with libmodbus RTS). */
struct rs485_origin {
    int opt_line;             /* the first rs485_* key */
    char opt_key[CONF_NAME];
    int rts_line, delay_us_line;
    int kernel_line;          /* the first kernel-only key */
    char kernel_key[CONF_NAME];
};

/* Longest line kept whole (libinih's own limit, INI_MAX_LINE, is 200):
 * an empty section's error quotes its header's name in full. */
#define CONF_LINE_CAP 256

struct parse {
    struct conf c;
    int listen_set;      /* first tcp_listen replaces the default */
    int models_set;      /* first [model:N] replaces the default */
    char err[256];
    char sec[64], key[64];  /* where the first error was raised */
    int err_line, syntax;
    /* Lines are counted here (the reader), not by libinih, so a message
     * always names the physical line. */
    const char *text;         /* the whole file, read by read_conf     */
    size_t len, pos;
    char *lbuf;
    size_t lcap;
    int line, bad_line, maxline;
    int nkeys;                /* keys in the whole file                 */
    /* The first line that is neither blank, a comment, a header nor a
     * "key = value" (libinih calls it a syntax error, without saying why). */
    int noeq_line;
    char noeq_text[64], noeq_sec[64];
    const char *bad_why;
    /* The section being read: its header line and name, and whether a key
     * of it was seen (an empty section is an error: its keys are missing). */
    int sec_line, sec_keys;
    char sec_name[CONF_LINE_CAP]; /* whole: reader() refuses longer lines */
    int empty_line;           /* first empty section's header line     */
    char empty_name[CONF_LINE_CAP];
    int max_models_line, grid_line, default_model_line;
    char grid_key[CONF_NAME];
    struct origin model[CONF_MAX_MODELS], rtu[CONF_MAX_RTU], link[CONF_MAX_LINKS], listen[CONF_MAX_LISTEN];
    int listen_addr_line[CONF_MAX_LISTEN]; /* 0: the listener has no address yet */
    struct rs485_origin rs485[CONF_MAX_RTU];
    /* Every (section, key) set so far, for duplicate keys (heap, freed
     * with the parse). */
    struct seen_key { char sec[64], key[64]; int line; } *seen;
    int nseen, cap_seen;
};

/* A key given twice in one section (or in two sections of the same name)
 * would silently take the last value: an error naming the first line.
 * tcp_listen and allow add up and may repeat. Returns that first line. */
static int duplicate_key(struct parse *p, const char *section, const char *name)
{
    if ((!strcmp(section, "modbus") && !strcmp(name, "tcp_listen")) ||
        (!strncmp(section, "listen:", 7) && !strcmp(name, "allow")))
        return 0;
    for (int k = 0; k < p->nseen; k++)
        if (!strcmp(p->seen[k].sec, section) && !strcmp(p->seen[k].key, name))
            return p->seen[k].line;
    if (p->nseen == p->cap_seen) {
        int cap = p->cap_seen ? 2 * p->cap_seen : 64;
        struct seen_key *s = realloc(p->seen, (size_t)cap * sizeof *s);
        if (!s)
            return 0;  /* no memory: the check is skipped, nothing breaks */
        p->seen = s;
        p->cap_seen = cap;
    }
    snprintf(p->seen[p->nseen].sec, sizeof p->seen[p->nseen].sec, "%s", section);
    snprintf(p->seen[p->nseen].key, sizeof p->seen[p->nseen].key, "%s", name);
    p->seen[p->nseen++].line = p->line;
    return 0;
}

static int parse_int(const char *v, long lo, long hi, int *out)
{
    char *end;
    long x = strtol(v, &end, 0);
    if (!*v || *end || x < lo || x > hi)
        return -1;
    *out = (int)x;
    return 0;
}

static int parse_bool(const char *v, int *out)
{
    if (!strcasecmp(v, "yes") || !strcasecmp(v, "true") || !strcmp(v, "1") || !strcasecmp(v, "on"))
        *out = 1;
    else if (!strcasecmp(v, "no") || !strcasecmp(v, "false") || !strcmp(v, "0") || !strcasecmp(v, "off"))
        *out = 0;
    else
        return -1;
    return 0;
}

static int copy_str(char *dst, size_t size, const char *v)
{
    size_t len = strlen(v);
    if (len == 0 || len >= size)
        return -1;
    memcpy(dst, v, len + 1);
    return 0;
}

/* "host:port", "[v6]:port" or ":port" (all IPv4 and IPv6). */
static int parse_listen(const char *v, struct conf_listen *l)
{
    const char *colon;
    size_t hlen;
    if (v[0] == '[') {
        const char *close = strchr(v, ']');
        if (!close || close[1] != ':')
            return -1;
        hlen = (size_t)(close - v - 1);
        if (hlen >= sizeof l->host)
            return -1;
        memcpy(l->host, v + 1, hlen);
        l->host[hlen] = 0;
        colon = close + 1;
    } else {
        colon = strrchr(v, ':');
        if (!colon)
            return -1;
        hlen = (size_t)(colon - v);
        if (hlen >= sizeof l->host)
            return -1;
        memcpy(l->host, v, hlen);
        l->host[hlen] = 0;
    }
    int port;
    if (parse_int(colon + 1, 0, 65535, &port))
        return -1;
    if (port == 0)
        return -2;  /* the kernel would pick a port no client knows */
    snprintf(l->port, sizeof l->port, "%d", port);
    return 0;
}

static int parse_order(const char *v, int *out)
{
    static const char *const names[] = { "ABCD", "CDAB", "BADC", "DCBA" };
    for (int k = 0; k < 4; k++)
        if (!strcasecmp(v, names[k])) {
            *out = k;
            return 0;
        }
    return -1;
}

static int parse_usb(const char *v, struct conf_link *l)
{
    unsigned vid, pid;
    int used = 0;
    if (sscanf(v, "%4x:%4x%n", &vid, &pid, &used) != 2)
        return -1;
    l->vid = (uint16_t)vid;
    l->pid = (uint16_t)pid;
    l->serial[0] = 0;
    if (v[used] == ':')
        return copy_str(l->serial, sizeof l->serial, v + used + 1);
    return v[used] ? -1 : 0;
}

#define FAIL(...) do { snprintf(p->err, sizeof p->err, __VA_ARGS__); p->err_line = p->line; return 0; } while (0)

static void note(struct parse *p, struct origin *o, const char *name)
{
    if (!o->first_line) {
        o->first_line = p->line;
        snprintf(o->first_key, sizeof o->first_key, "%s", name);
    }
    if (!strcmp(name, "unit_id"))
        o->unit_line = p->line;
    else if (!strcmp(name, "preload"))
        o->preload_line = p->line;
    else if (!strcmp(name, "removed"))
        o->removed_line = p->line;
    else if (!strcmp(name, "n"))
        o->n_line = p->line;
    else if (!strcmp(name, "m"))
        o->m_line = p->line;
    else if (!strcmp(name, "kind"))
        o->kind_line = p->line;
    else if (!strcmp(name, "chord"))
        o->chord_line = p->line;
}

static void note_rs485(const struct parse *p, struct rs485_origin *o, const char *name)
{
    if (strncmp(name, "rs485_", 6))
        return;
    if (!o->opt_line) {
        o->opt_line = p->line;
        snprintf(o->opt_key, sizeof o->opt_key, "%s", name);
    }
    if (!strcmp(name, "rs485_rts"))
        o->rts_line = p->line;
    else if (!strcmp(name, "rs485_rts_delay_us"))
        o->delay_us_line = p->line;
    else if (strcmp(name, "rs485_strict") && !o->kernel_line) {
        o->kernel_line = p->line;
        snprintf(o->kernel_key, sizeof o->kernel_key, "%s", name);
    }
}

static int key_daemon(struct parse *p, const char *name, const char *v)
{
    struct conf *c = &p->c;
    if (!strcmp(name, "state_dir")) {
        if (copy_str(c->state_dir, sizeof c->state_dir, v))
            FAIL("path empty or too long");
    } else if (!strcmp(name, "snapshot_interval")) {
        if (parse_int(v, 1, 86400, &c->snapshot_interval))
            FAIL("expected seconds 1..86400");
    } else if (!strcmp(name, "fsync")) {
        if (parse_bool(v, &c->fsync))
            FAIL("expected yes or no");
    } else if (!strcmp(name, "max_models")) {
        if (parse_int(v, 1, CONF_MAX_MODELS, &c->max_models))
            FAIL("expected 1..%d", CONF_MAX_MODELS);
    } else if (!strcmp(name, "link_backoff_max")) {
        if (parse_int(v, 1, 3600, &c->link_backoff_max))
            FAIL("expected seconds 1..3600");
    } else if (!strcmp(name, "user")) {
        /* Resolved now, so a typo is a config error with file:line rather
         * than a failure after the sockets are open. */
        const struct passwd *pw = getpwnam(v);
        if (copy_str(c->user, sizeof c->user, v))
            FAIL("name empty or too long");
        if (!pw)
            FAIL("unknown user '%s'", v);
        c->uid = (unsigned)pw->pw_uid;
        c->gid = (unsigned)pw->pw_gid;
    } else {
        FAIL("unknown key");
    }
    return 1;
}

static int key_modbus(struct parse *p, const char *name, const char *v)
{
    struct conf *c = &p->c;
    if (!strcmp(name, "tcp_listen")) {
        if (!p->listen_set) {
            c->nlisten = 0;
            p->listen_set = 1;
        }
        if (!strcasecmp(v, "none"))
            return 1;
        if (c->nlisten == CONF_MAX_LISTEN)
            FAIL("more than %d listen addresses", CONF_MAX_LISTEN);
        memset(&c->listen[c->nlisten], 0, sizeof c->listen[c->nlisten]);
        int rc = parse_listen(v, &c->listen[c->nlisten]);
        if (rc == -2)
            FAIL("port 0: expected a port 1..65535 (0 would be a random port no client knows)");
        if (rc)
            FAIL("expected host:port, [v6addr]:port or :port");
        c->listen[c->nlisten].line = p->line;
        p->listen_addr_line[c->nlisten] = p->line;
        c->nlisten++;
    } else if (!strcmp(name, "max_clients")) {
        if (parse_int(v, 1, 512, &c->max_clients))
            FAIL("expected 1..512");
    } else if (!strcmp(name, "max_pending")) {
        if (parse_int(v, 16, 65536, &c->max_pending))
            FAIL("expected 16..65536");
    } else if (!strcmp(name, "idle_timeout")) {
        if (parse_int(v, 1, 86400, &c->idle_timeout))
            FAIL("expected seconds 1..86400");
    } else if (!strcmp(name, "byte_timeout")) {
        if (parse_int(v, 10, 60000, &c->byte_timeout))
            FAIL("expected milliseconds 10..60000");
    } else if (!strcmp(name, "tcp_keepalive")) {
        if (parse_int(v, 0, 7200, &c->tcp_keepalive))
            FAIL("expected seconds 0..7200 (0: off)");
    } else if (!strcmp(name, "evict_idle")) {
        if (parse_int(v, 0, 86400000, &c->evict_idle))
            FAIL("expected milliseconds 0..86400000");
    } else if (!strcmp(name, "float_word_order")) {
        if (parse_order(v, &c->word_order))
            FAIL("expected ABCD, CDAB, BADC or DCBA");
    } else if (!strcmp(name, "int32_word_order")) {
        if (!strcasecmp(v, "float"))
            c->int32_word_order = -1;
        else if (parse_order(v, &c->int32_word_order))
            FAIL("expected float (as float_word_order), ABCD, CDAB, BADC or DCBA");
    } else if (!strcmp(name, "default_model")) {
        if (!strcasecmp(v, "auto"))
            c->default_model = CONF_DEFAULT_AUTO;
        else if (!strcasecmp(v, "none"))
            c->default_model = CONF_DEFAULT_NONE;
        else if (parse_int(v, 0, 254, &c->default_model))
            FAIL("expected auto, none or a model id 0..254");
        p->default_model_line = p->line;
    } else if (!strcmp(name, "coord_scale")) {
        if (parse_int(v, 1, 10000, &c->coord_scale))
            FAIL("expected 1..10000");
    } else if (!strcmp(name, "grid_rows")) {
        if (parse_int(v, 2, 16, &c->grid_rows))
            FAIL("expected 2..16");
    } else if (!strcmp(name, "grid_cols")) {
        if (parse_int(v, 2, 16, &c->grid_cols))
            FAIL("expected 2..16");
    } else {
        FAIL("unknown key");
    }
    return 1;
}

/* [listen:NAME]: one TCP listener with its access policy. */
static int key_listen(struct parse *p, int k, const char *name, const char *v)
{
    struct conf_listen *l = &p->c.listen[k];
    if (!strcmp(name, "address")) {
        char nm[CONF_NAME];
        memcpy(nm, l->name, sizeof nm);
        int rc = parse_listen(v, l);
        if (rc == -2)
            FAIL("port 0: expected a port 1..65535 (0 would be a random port no client knows)");
        if (rc)
            FAIL("expected host:port, [v6addr]:port or :port");
        memcpy(l->name, nm, sizeof nm);
        l->line = p->line;
        p->listen_addr_line[k] = p->line;
    } else if (!strcmp(name, "allow")) {
        char buf[256], *tok, *save = NULL, why[160];
        snprintf(buf, sizeof buf, "%s", v);
        if (!v[strspn(v, ", \t")]) /* "allow =" must not read as "everyone" */
            FAIL("expected IPv4/IPv6 addresses or prefixes");
        for (tok = strtok_r(buf, ", \t", &save); tok; tok = strtok_r(NULL, ", \t", &save)) {
            if (l->nallow == CONF_MAX_ALLOW)
                FAIL("more than %d allow entries in this section", CONF_MAX_ALLOW);
            if (acl_parse_prefix(tok, &l->allow[l->nallow], why, sizeof why))
                FAIL("%s", why);
            l->nallow++;
        }
    } else if (!strcmp(name, "read_only")) {
        if (parse_bool(v, &l->read_only))
            FAIL("expected yes or no");
    } else {
        FAIL("unknown key");
    }
    return 1;
}

static int key_rtu(struct parse *p, struct conf_rtu *r, const char *name, const char *v)
{
    if (!strcmp(name, "device")) {
        if (copy_str(r->device, sizeof r->device, v))
            FAIL("path empty or too long");
        r->device_line = p->line;
    } else if (!strcmp(name, "baud")) {
        if (parse_int(v, 1200, 4000000, &r->baud))
            FAIL("expected 1200..4000000");
    } else if (!strcmp(name, "parity")) {
        if (!strcasecmp(v, "none") || !strcasecmp(v, "N"))
            r->parity = 'N';
        else if (!strcasecmp(v, "even") || !strcasecmp(v, "E"))
            r->parity = 'E';
        else if (!strcasecmp(v, "odd") || !strcasecmp(v, "O"))
            r->parity = 'O';
        else
            FAIL("expected none, even or odd");
    } else if (!strcmp(name, "stop_bits")) {
        if (parse_int(v, 1, 2, &r->stop_bits))
            FAIL("expected 1 or 2");
    } else if (!strcmp(name, "read_only")) {
        if (parse_bool(v, &r->read_only))
            FAIL("expected yes or no");
    } else if (!strcmp(name, "t35_us")) {
        if (!strcasecmp(v, "auto"))
            r->t35_us = 0;
        else if (parse_int(v, 500, 1000000, &r->t35_us))
            FAIL("expected auto or microseconds 500..1000000");
    } else if (!strcmp(name, "rs485")) {
        if (parse_bool(v, &r->rs485))
            FAIL("expected yes or no");
    } else if (!strcmp(name, "rs485_rts")) {
        if (!strcasecmp(v, "none"))
            r->rts = CONF_RTS_NONE;
        else if (!strcasecmp(v, "up"))
            r->rts = CONF_RTS_UP;
        else if (!strcasecmp(v, "down"))
            r->rts = CONF_RTS_DOWN;
        else
            FAIL("expected none, up or down");
    } else if (!strcmp(name, "rs485_rts_delay_us")) {
        if (parse_int(v, 0, CONF_RTS_DELAY_US_MAX, &r->rts_delay_us))
            FAIL("expected microseconds 0..%d", CONF_RTS_DELAY_US_MAX);
    } else if (!strcmp(name, "rs485_rts_on_send")) {
        if (!strcasecmp(v, "high"))
            r->rts_on_send = 1;
        else if (!strcasecmp(v, "low"))
            r->rts_on_send = 0;
        else
            FAIL("expected high or low");
    } else if (!strcmp(name, "rs485_delay_before_send_ms") || !strcmp(name, "rs485_delay_after_send_ms")) {
        int *d = !strcmp(name, "rs485_delay_before_send_ms") ? &r->delay_before_ms : &r->delay_after_ms;
        if (parse_int(v, 0, CONF_RS485_DELAY_MS_MAX, d))
            FAIL("expected milliseconds 0..%d (the kernel's limit)", CONF_RS485_DELAY_MS_MAX);
    } else if (!strcmp(name, "rs485_termination")) {
        if (parse_bool(v, &r->termination))
            FAIL("expected yes or no");
    } else if (!strcmp(name, "rs485_strict")) {
        if (parse_bool(v, &r->strict))
            FAIL("expected yes or no");
    } else {
        FAIL("unknown key");
    }
    return 1;
}

static int key_model(struct parse *p, struct conf_model *m, const char *name, const char *v)
{
    int b;
    if (!strcmp(name, "unit_id")) {
        if (parse_int(v, 1, 247, &m->unit))
            FAIL("expected 1..247");
    } else if (!strcmp(name, "n") || !strcmp(name, "m")) {
        /* The kind's own limit is checked once the section is read (kind
         * may come after n and m). */
        if (parse_int(v, 1, IT2N_BSPLINE_MAX_N, name[0] == 'n' ? &m->n : &m->m))
            FAIL("expected 1..%d (bezier: 1..%d)", IT2N_BSPLINE_MAX_N, IT2N_MAX_DEGREE);
        m->set |= name[0] == 'n' ? CONF_SET_N : CONF_SET_M;
    } else if (!strcmp(name, "kind")) {
        if (!strcmp(v, "bezier"))
            m->kind = CONF_KIND_BEZIER;
        else if (!strcmp(v, "bspline"))
            m->kind = CONF_KIND_BSPLINE;
        else
            FAIL("expected bezier or bspline");
        m->set |= CONF_SET_KIND;
    } else if (!strcmp(name, "z") || !strcmp(name, "type1") || !strcmp(name, "chord")) {
        unsigned bit = name[0] == 'z' ? IT2N_F_Z : name[0] == 't' ? IT2N_F_TYPE1 : IT2N_F_CHORD;
        if (parse_bool(v, &b))
            FAIL("expected yes or no");
        m->flags = b ? (m->flags | bit) : (m->flags & ~bit);
        m->set |= name[0] == 'z' ? CONF_SET_Z : name[0] == 't' ? CONF_SET_TYPE1 : CONF_SET_CHORD;
    } else if (!strcmp(name, "write_protect")) {
        if (parse_bool(v, &m->write_protect))
            FAIL("expected yes or no");
    } else if (!strcmp(name, "preload")) {
        if (!strcmp(v, "paper"))
            m->preload = 1;
        else if (!strcmp(v, "none"))
            m->preload = 0;
        else
            FAIL("expected paper or none");
    } else if (!strcmp(name, "removed")) {
        if (parse_bool(v, &m->removed))
            FAIL("expected yes or no");
    } else {
        FAIL("unknown key");
    }
    return 1;
}

static int key_link(struct parse *p, struct conf_link *l, const char *name, const char *v)
{
    if (!strcmp(name, "type")) {
        if (!strcmp(v, "serial"))
            l->type = CONF_LINK_SERIAL;
        else if (!strcmp(v, "usb"))
            l->type = CONF_LINK_USB;
        else
            FAIL("expected serial or usb");
    } else if (!strcmp(name, "device")) {
        if (copy_str(l->device, sizeof l->device, v))
            FAIL("path empty or too long");
        l->device_line = p->line;
    } else if (!strcmp(name, "baud")) {
        if (parse_int(v, 1200, 4000000, &l->baud))
            FAIL("expected 1200..4000000");
    } else if (!strcmp(name, "usb")) {
        if (parse_usb(v, l))
            FAIL("expected VID:PID[:serial] in hex");
    } else if (!strcmp(name, "rto_ms")) {
        if (parse_int(v, 1, 60000, &l->rto_ms))
            FAIL("expected 1..60000 (ms)");
    } else if (!strcmp(name, "peer_timeout_ms")) {
        if (parse_int(v, 100, 3600000, &l->peer_timeout_ms))
            FAIL("expected 100..3600000 (ms)");
    } else {
        FAIL("unknown key");
    }
    return 1;
}

/* [metrics]: the Prometheus endpoint, off unless listen is given. */
static int key_metrics(struct parse *p, const char *name, const char *v)
{
    struct conf_metrics *m = &p->c.metrics;
    if (!strcmp(name, "listen")) {
        struct conf_listen l;
        int rc;
        memset(&l, 0, sizeof l);
        if (!strcasecmp(v, "none")) {
            memset(m, 0, sizeof *m);
            return 1;
        }
        rc = parse_listen(v, &l);
        if (rc == -2)
            FAIL("port 0: expected a port 1..65535 (Prometheus must know where to scrape)");
        if (rc)
            FAIL("expected host:port, [v6addr]:port, :port or none");
        memcpy(m->host, l.host, sizeof m->host);
        memcpy(m->port, l.port, sizeof m->port);
        m->line = p->line;
    } else {
        FAIL("unknown key");
    }
    return 1;
}

/* Named sections "kind:NAME": find or create the entry for NAME. */
static int handler(void *user, const char *section, const char *name, const char *value)
{
    struct parse *p = user;
    struct conf *c = &p->c;
    if (!name)  /* section start without keys (INI_CALL_HANDLER_ON_NEW_SECTION) */
        return 1;
    if (p->err[0])  /* libinih goes on after an error: keep the first */
        return 1;
    if (!name[0]) {  /* " = value": libinih passes an empty name */
        p->syntax = 1;
        FAIL("key name missing before '='");
    }
    snprintf(p->sec, sizeof p->sec, "%s", section);
    snprintf(p->key, sizeof p->key, "%s", name);
    p->sec_keys++;
    p->nkeys++;
    {
        int first = duplicate_key(p, section, name);
        if (first)
            FAIL("duplicate key (first set on line %d)", first);
    }
    if (!strcmp(section, "daemon")) {
        if (!strcmp(name, "max_models"))
            p->max_models_line = p->line;
        return key_daemon(p, name, value);
    }
    if (!strcmp(section, "modbus")) {
        if (!strcmp(name, "grid_rows") || !strcmp(name, "grid_cols")) {
            p->grid_line = p->line;
            snprintf(p->grid_key, sizeof p->grid_key, "%s", name);
        }
        return key_modbus(p, name, value);
    }
    if (!strcmp(section, "sparkplug")) {
        if (spb_conf_key(&c->spb, name, value, p->line, p->err, sizeof p->err))
            p->err_line = p->line;
        return !p->err[0];
    }
    if (!strcmp(section, "metrics"))
        return key_metrics(p, name, value);
    if (!strncmp(section, "listen:", 7) && section[7]) {
        int k;
        if (!p->listen_set) {
            c->nlisten = 0;
            p->listen_set = 1;
        }
        for (k = 0; k < c->nlisten; k++)
            if (!strcmp(c->listen[k].name, section + 7))
                break;
        if (k == c->nlisten) {
            if (k == CONF_MAX_LISTEN)
                FAIL("more than %d listen addresses", CONF_MAX_LISTEN);
            memset(&c->listen[k], 0, sizeof c->listen[k]);
            if (copy_str(c->listen[k].name, sizeof c->listen[k].name, section + 7))
                FAIL("section name too long");
            p->listen_addr_line[k] = 0;
            memset(&p->listen[k], 0, sizeof p->listen[k]);
            c->nlisten++;
        }
        note(p, &p->listen[k], name);
        return key_listen(p, k, name, value);
    }
    if (!strncmp(section, "rtu:", 4) && section[4]) {
        int k;
        for (k = 0; k < c->nrtu; k++)
            if (!strcmp(c->rtu[k].name, section + 4))
                break;
        if (k == c->nrtu) {
            if (k == CONF_MAX_RTU)
                FAIL("more than %d [rtu:] sections", CONF_MAX_RTU);
            memset(&c->rtu[k], 0, sizeof c->rtu[k]);
            if (copy_str(c->rtu[k].name, sizeof c->rtu[k].name, section + 4))
                FAIL("section name too long");
            c->rtu[k].baud = 19200;
            c->rtu[k].parity = 'E';
            c->rtu[k].stop_bits = 1;
            c->rtu[k].rts_delay_us = -1;
            c->rtu[k].rts_on_send = -1;
            c->rtu[k].delay_before_ms = -1;
            c->rtu[k].delay_after_ms = -1;
            c->rtu[k].termination = -1;
            c->nrtu++;
        }
        note(p, &p->rtu[k], name);
        note_rs485(p, &p->rs485[k], name);
        return key_rtu(p, &c->rtu[k], name, value);
    }
    if (!strncmp(section, "model:", 6)) {
        int id, k;
        if (parse_int(section + 6, 0, 254, &id))
            FAIL("model section must be [model:ID], ID 0..254 (the model id on the links)");
        if (!p->models_set) {
            c->nmodels = 0;
            p->models_set = 1;
        }
        for (k = 0; k < c->nmodels; k++)
            if (c->model[k].id == id)
                break;
        if (k == c->nmodels) {
            if (k == CONF_MAX_MODELS)
                FAIL("more than %d models", CONF_MAX_MODELS);
            memset(&c->model[k], 0, sizeof c->model[k]);
            c->model[k].id = id;
            c->model[k].unit = id >= 1 && id <= 247 ? id : 0;
            c->model[k].n = 3;
            c->model[k].m = 3;
            c->nmodels++;
        }
        note(p, &p->model[k], name);
        return key_model(p, &c->model[k], name, value);
    }
    if (!strncmp(section, "link:", 5) && section[5]) {
        int k;
        for (k = 0; k < c->nlinks; k++)
            if (!strcmp(c->link[k].name, section + 5))
                break;
        if (k == c->nlinks) {
            if (k == CONF_MAX_LINKS)
                FAIL("more than %d links", CONF_MAX_LINKS);
            memset(&c->link[k], 0, sizeof c->link[k]);
            if (copy_str(c->link[k].name, sizeof c->link[k].name, section + 5))
                FAIL("section name too long");
            c->link[k].baud = 115200;
            c->link[k].peer_timeout_ms = 30000;
            c->nlinks++;
        }
        note(p, &p->link[k], name);
        return key_link(p, &c->link[k], name, value);
    }
    FAIL("unknown section");
}

void conf_default(struct conf *c)
{
    memset(c, 0, sizeof *c);
    snprintf(c->state_dir, sizeof c->state_dir, "./state");
    c->snapshot_interval = 60;
    c->fsync = 1;
    c->max_models = 8;
    snprintf(c->listen[0].host, sizeof c->listen[0].host, "127.0.0.1");
    snprintf(c->listen[0].port, sizeof c->listen[0].port, "1502");
    c->nlisten = 1;
    c->max_clients = 32;
    c->max_pending = 1024;
    c->idle_timeout = 300;
    c->byte_timeout = 500;
    c->tcp_keepalive = 60;
    c->evict_idle = 500;
    c->word_order = IT2N_WO_ABCD;
    c->int32_word_order = -1;
    c->default_model = CONF_DEFAULT_AUTO;
    c->coord_scale = 100;
    c->grid_rows = 5;
    c->grid_cols = 5;
    c->model[0].id = 1;
    c->model[0].unit = 1;
    c->model[0].n = 3;
    c->model[0].m = 3;
    c->model[0].preload = 1;
    c->nmodels = 1;
    c->link_backoff_max = 30;
    spb_conf_default(&c->spb);
}

/* Cross-key checks, done after the whole file is read. Each error names
 * the line of a key involved (or, for a missing key, the section's first
 * key): *line and *key are set, err gets "[section] key: reason". */
#define VFAIL(l, sec, k, ...) do { \
        *line = (l); \
        snprintf(key, keysize, "%s", (k)); \
        snprintf(sect, sectsize, "%s", (sec)); \
        snprintf(err, errsize, __VA_ARGS__); \
        return -1; \
    } while (0)

/* [model:ID] sections with removed = yes leave the model list (their
 * unit id is free, they do not count in max_models) for conf.removed, the
 * operator's consent to discard what the state holds for them. Their
 * origins move with the models, so later errors name the right lines. */
static int split_removed(struct parse *p, int *line, char *sect, size_t sectsize, char *key, size_t keysize,
                         char *err, size_t errsize)
{
    struct conf *c = &p->c;
    int w = 0, last = -1;
    for (int k = 0; k < c->nmodels; k++) {
        if (c->model[k].removed) {
            c->removed[c->nremoved++] = c->model[k].id;
            last = k;
            continue;
        }
        c->model[w] = c->model[k];
        p->model[w] = p->model[k];
        w++;
    }
    if (last >= 0 && w == 0) {
        char sec[64];
        snprintf(sec, sizeof sec, "model:%d", c->model[last].id);
        VFAIL(p->model[last].removed_line, sec, "removed",
              "every [model:] section says removed = yes: at least one model must be served");
    }
    c->nmodels = w;
    return 0;
}

/* The device of an [rtu:] or serial [link:] section. */
struct dev_ref {
    const char *kind, *name, *device;
    int line;
};

static int device_refs(const struct conf *c, struct dev_ref *d)
{
    int n = 0;
    for (int k = 0; k < c->nrtu; k++)
        if (c->rtu[k].device[0])
            d[n++] = (struct dev_ref){ "rtu", c->rtu[k].name, c->rtu[k].device, c->rtu[k].device_line };
    for (int k = 0; k < c->nlinks; k++)
        if (c->link[k].type == CONF_LINK_SERIAL && c->link[k].device[0])
            d[n++] = (struct dev_ref){ "link", c->link[k].name, c->link[k].device, c->link[k].device_line };
    return n;
}

/* The pair of d[] on one device whose later line comes first in the file
 * (same(a, b) decides); returns 0 and *a (earlier), *b (later) or -1. */
static int first_conflict(const struct dev_ref *d, int n, int (*same)(const struct dev_ref *, const struct dev_ref *),
                          int *a, int *b)
{
    int best = -1;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < j; i++) {
            int later = d[i].line > d[j].line ? i : j, earlier = later == i ? j : i;
            if ((best < 0 || d[later].line < d[*b].line) && same(&d[i], &d[j])) {
                best = 0;
                *a = earlier;
                *b = later;
            }
        }
    return best;
}

static int same_path(const struct dev_ref *x, const struct dev_ref *y)
{
    return !strcmp(x->device, y->device);
}

#define DEV_CONFLICT_WHY "one device serves one section (the other would find it locked by another process)"

static int validate(const struct parse *p, int *line, char *sect, size_t sectsize, char *key, size_t keysize,
                    char *err, size_t errsize)
{
    const struct conf *c = &p->c;
    char sec[64];
    if (c->default_model >= 0) {
        int k = 0;
        while (k < c->nmodels && c->model[k].id != c->default_model)
            k++;
        if (k == c->nmodels)
            VFAIL(p->default_model_line, "modbus", "default_model", "no [model:%d] is configured", c->default_model);
    }
    if (c->nmodels > c->max_models) {
        const struct origin *o = &p->model[c->max_models];
        snprintf(sec, sizeof sec, "model:%d", c->model[c->max_models].id);
        if (p->max_models_line)
            VFAIL(p->max_models_line > o->first_line ? p->max_models_line : o->first_line, "daemon", "max_models",
                  "%d models configured, limit %d", c->nmodels, c->max_models);
        VFAIL(o->first_line, sec, o->first_key, "model %d of at most max_models = %d (the default; set max_models in [daemon])",
              c->max_models + 1, c->max_models);
    }
    if (c->grid_rows * c->grid_cols > (int)IT2N_REGMAP_GRID_MAX_NODES)
        VFAIL(p->grid_line, "modbus", p->grid_key, "grid_rows x grid_cols = %d x %d exceeds %u nodes", c->grid_rows,
              c->grid_cols, IT2N_REGMAP_GRID_MAX_NODES);
    for (int k = 0; k < c->nmodels; k++) {
        const struct conf_model *m = &c->model[k];
        const struct origin *o = &p->model[k];
        snprintf(sec, sizeof sec, "model:%d", m->id);
        if (m->unit < 1)
            VFAIL(o->first_line, sec, o->first_key, "unit_id is required for model ids 0 and above 247");
        for (int l = 0; l < k; l++)
            if (c->model[l].unit == m->unit) {
                if (o->unit_line)
                    VFAIL(o->unit_line, sec, "unit_id", "%d already used by model %d", m->unit, c->model[l].id);
                VFAIL(p->model[l].unit_line ? p->model[l].unit_line : o->first_line, sec,
                      p->model[l].unit_line ? "unit_id" : o->first_key, "unit id %d (the model id) already used by model %d",
                      m->unit, c->model[l].id);
            }
        if (m->kind == CONF_KIND_BEZIER && (m->n > IT2N_MAX_DEGREE || m->m > IT2N_MAX_DEGREE)) {
            int ln = m->n > IT2N_MAX_DEGREE ? o->n_line : o->m_line;
            VFAIL(ln, sec, m->n > IT2N_MAX_DEGREE ? "n" : "m",
                  "%d exceeds the bezier kind's degree limit %d; use 1..%d, or kind = bspline for grids up to %d",
                  m->n > IT2N_MAX_DEGREE ? m->n : m->m, IT2N_MAX_DEGREE, IT2N_MAX_DEGREE, IT2N_BSPLINE_MAX_N);
        }
        if (m->kind == CONF_KIND_BSPLINE && (m->flags & IT2N_F_CHORD))
            VFAIL(o->chord_line ? o->chord_line : o->kind_line, sec, o->chord_line ? "chord" : "kind",
                  "the bspline kind has uniform parameters only: chord = yes needs kind = bezier");
        if (m->preload && (m->n != 3 || m->m != 3 || (m->flags & (IT2N_F_Z | IT2N_F_TYPE1))))
            VFAIL(o->preload_line ? o->preload_line : o->first_line, sec, o->preload_line ? "preload" : o->first_key,
                  "the paper data set needs n = m = 3, no z, not type1");
    }
    for (int k = 0; k < c->nlisten; k++) {
        const struct conf_listen *l = &c->listen[k];
        if (!l->name[0])
            continue;
        snprintf(sec, sizeof sec, "listen:%s", l->name);
        if (!p->listen_addr_line[k])
            VFAIL(p->listen[k].first_line, sec, p->listen[k].first_key, "address is required in this section");
    }
    for (int k = 0; k < c->nlisten; k++)
        for (int j = 0; j < k; j++)
            if (!strcmp(c->listen[k].host, c->listen[j].host) && !strcmp(c->listen[k].port, c->listen[j].port)) {
                snprintf(sec, sizeof sec, "%s%s", c->listen[k].name[0] ? "listen:" : "modbus",
                         c->listen[k].name);
                VFAIL(p->listen_addr_line[k], sec, c->listen[k].name[0] ? "address" : "tcp_listen",
                      "%s%s%s:%s is already a listener address", strchr(c->listen[k].host, ':') ? "[" : "",
                      c->listen[k].host, strchr(c->listen[k].host, ':') ? "]" : "", c->listen[k].port);
            }
    for (int k = 0; k < c->nlisten && c->metrics.port[0]; k++)
        if (!strcmp(c->listen[k].host, c->metrics.host) && !strcmp(c->listen[k].port, c->metrics.port))
            VFAIL(c->metrics.line, "metrics", "listen", "%s:%s is also a Modbus listener address (%s%.0d): "
                  "the metrics endpoint needs a port of its own", c->metrics.host, c->metrics.port,
                  c->listen[k].line ? "line " : "the built-in default", c->listen[k].line);
    for (int k = 0; k < c->nrtu; k++) {
        const struct conf_rtu *r = &c->rtu[k];
        const struct rs485_origin *o = &p->rs485[k];
        snprintf(sec, sizeof sec, "rtu:%s", r->name);
        if (!r->device[0])
            VFAIL(p->rtu[k].first_line, sec, p->rtu[k].first_key, "device is required in this section");
        if (!r->rs485 && o->opt_line)
            VFAIL(o->opt_line, sec, o->opt_key, "needs rs485 = yes in this section");
        if (r->rts == CONF_RTS_NONE && o->delay_us_line)
            VFAIL(o->delay_us_line, sec, "rs485_rts_delay_us", "needs rs485_rts = up or down (libmodbus switching RTS)");
        if (r->rts != CONF_RTS_NONE && o->kernel_line)
            VFAIL(o->kernel_line, sec, o->kernel_key,
                  "a kernel RS-485 option, but rs485_rts = %s (line %d) has libmodbus switch RTS instead; "
                  "use one or the other", r->rts == CONF_RTS_UP ? "up" : "down", o->rts_line);
    }
    for (int k = 0; k < c->nlinks; k++) {
        const struct conf_link *l = &c->link[k];
        snprintf(sec, sizeof sec, "link:%s", l->name);
        if (l->type == CONF_LINK_SERIAL && !l->device[0])
            VFAIL(p->link[k].first_line, sec, p->link[k].first_key, "device is required for type serial");
        if (l->type == CONF_LINK_USB && !l->vid && !l->pid)
            VFAIL(p->link[k].first_line, sec, p->link[k].first_key, "usb is required for type usb");
    }
    {
        struct dev_ref d[CONF_MAX_RTU + CONF_MAX_LINKS];
        int n = device_refs(c, d), a = 0, b = 0;
        if (!first_conflict(d, n, same_path, &a, &b)) {
            snprintf(sec, sizeof sec, "%s:%s", d[b].kind, d[b].name);
            VFAIL(d[b].line, sec, "device", "%s is also the device of [%s:%s] (line %d): " DEV_CONFLICT_WHY,
                  d[b].device, d[a].kind, d[a].name, d[a].line);
        }
    }
    if (spb_conf_check(&c->spb, line, key, keysize, err, errsize)) {
        snprintf(sect, sectsize, "sparkplug");
        return -1;
    }
    return 0;
}

/* The section read so far ends (a new header or the end of the file):
 * remember it if no key was given in it. */
static void section_end(struct parse *p)
{
    if (p->sec_line && !p->sec_keys && !p->empty_line) {
        p->empty_line = p->sec_line;
        snprintf(p->empty_name, sizeof p->empty_name, "%s", p->sec_name);
    }
}

/* A "[name]" header line (as libinih sees one: leading blanks allowed). */
static void section_start(struct parse *p, const char *l)
{
    const char *close;
    while (*l == ' ' || *l == '\t' || *l == '\r')
        l++;
    if (*l != '[' || !(close = strchr(l, ']')))
        return;
    section_end(p);
    p->sec_line = p->line;
    p->sec_keys = 0;
    snprintf(p->sec_name, sizeof p->sec_name, "%.*s", (int)(close - l - 1), l + 1);
}

/* A line libinih will refuse for want of '=' (or ':'): remember the first
 * for the message, and count it as an attempted key, so its section is
 * not reported "empty" instead. */
static void no_equals(struct parse *p, const char *l)
{
    size_t n;
    while (*l == ' ' || *l == '\t')
        l++;
    if (!*l || *l == '\n' || *l == '\r' || *l == ';' || *l == '#' || *l == '[' || strpbrk(l, "=:"))
        return;
    p->sec_keys++;
    if (p->noeq_line)
        return;
    p->noeq_line = p->line;
    n = strcspn(l, "\r\n");
    while (n > 0 && (l[n - 1] == ' ' || l[n - 1] == '\t'))
        n--;
    snprintf(p->noeq_text, sizeof p->noeq_text, "%.*s%s", (int)(n < 48 ? n : 48), l, n > 48 ? "..." : "");
    snprintf(p->noeq_sec, sizeof p->noeq_sec, "%.63s", p->sec_name);
}

/* libinih reader: one physical line of the file's text per call, counted;
 * a line that does not fit libinih's buffer (it would be split and its
 * tail parsed as a new line) or holds a NUL byte (a file whose blocks were
 * allocated but never written reads as zeros after a crash) stops the
 * parse and is reported. */
static char *reader(char *str, int num, void *stream)
{
    struct parse *p = stream;
    const char *l, *nl;
    size_t n;
    if (p->bad_line)
        return NULL;
    if (p->pos >= p->len) {
        section_end(p);
        return NULL;
    }
    l = p->text + p->pos;
    nl = memchr(l, '\n', p->len - p->pos);
    n = nl ? (size_t)(nl - l) + 1 : p->len - p->pos;
    p->pos += n;
    if (n + 1 > p->lcap) {
        char *b = realloc(p->lbuf, n + 1);
        if (!b) {
            p->bad_line = p->line + 1;
            p->bad_why = "out of memory";
            return NULL;
        }
        p->lbuf = b;
        p->lcap = n + 1;
    }
    memcpy(p->lbuf, l, n);
    p->lbuf[n] = 0;
    p->line++;
    section_start(p, p->lbuf);
    no_equals(p, p->lbuf);
    p->maxline = num - 2; /* room for the newline and the NUL */
    if (p->maxline > CONF_LINE_CAP - 1) /* a header's name must fit sec_name */
        p->maxline = CONF_LINE_CAP - 1;
    if (memchr(p->lbuf, 0, n)) {
        p->bad_line = p->line;
        p->bad_why = "NUL byte in the line";
        return NULL;
    }
    if (n - (p->lbuf[n - 1] == '\n') > (size_t)p->maxline) {
        p->bad_line = p->line;
        p->bad_why = "line too long";
        return NULL;
    }
    memcpy(str, p->lbuf, n + 1);
    return str;
}

/* What fstat says a path is, for "not a regular file". */
static const char *file_kind(mode_t mode)
{
    return S_ISDIR(mode) ? "a directory" : S_ISFIFO(mode) ? "a FIFO" : S_ISCHR(mode) ? "a character device" :
           S_ISBLK(mode) ? "a block device" : S_ISSOCK(mode) ? "a socket" : "not a regular file";
}

/* Read path whole into a NUL-terminated heap buffer, never blocking and
 * never opening anything but a regular file: stat first (a FIFO without
 * a writer, /dev/zero or a tty is refused without an open, so no DTR
 * toggles and nothing waits), then open with O_NONBLOCK and fstat again
 * (the path may have been replaced in between). At most CONF_MAX_BYTES;
 * a file whose size changes while it is read is being rewritten and is
 * refused. Returns the buffer or NULL with err written. */
static char *read_conf(const char *path, size_t *lenp, char *err, size_t errsize)
{
    struct stat st;
    char *buf = NULL;
    size_t len = 0;
    int fd;
    if (stat(path, &st)) {
        snprintf(err, errsize, "%s: cannot open: %s", path, strerror(errno));
        return NULL;
    }
    if (!S_ISREG(st.st_mode))
        goto not_regular;
    fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        snprintf(err, errsize, "%s: cannot open: %s", path, strerror(errno));
        return NULL;
    }
    if (fstat(fd, &st)) {
        snprintf(err, errsize, "%s: cannot read: %s", path, strerror(errno));
        goto fail;
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        goto not_regular;
    }
    if (st.st_size > CONF_MAX_BYTES) {
        snprintf(err, errsize, "%s: %lld bytes: larger than a configuration can be (%d bytes at most)", path,
                 (long long)st.st_size, CONF_MAX_BYTES);
        goto fail;
    }
    /* One byte more than fstat said, to see a file still growing. */
    buf = malloc((size_t)st.st_size + 2);
    if (!buf) {
        snprintf(err, errsize, "%s: out of memory", path);
        goto fail;
    }
    while (len < (size_t)st.st_size + 1) {
        ssize_t n = read(fd, buf + len, (size_t)st.st_size + 1 - len);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            snprintf(err, errsize, "%s: cannot read: %s", path, strerror(errno));
            goto fail;
        }
        if (n == 0)
            break;
        len += (size_t)n;
    }
    if (len != (size_t)st.st_size) {
        snprintf(err, errsize, "%s: changed while it was read (%lld bytes, then %zu%s): it is being rewritten; "
                 "reload once it is complete", path, (long long)st.st_size, len, len > (size_t)st.st_size ? " or more" : "");
        goto fail;
    }
    close(fd);
    buf[len] = 0;
    *lenp = len;
    return buf;
fail:
    free(buf);
    close(fd);
    return NULL;
not_regular:
    snprintf(err, errsize, "%s: %s, not a regular file: the configuration must be a regular file (nothing was read)",
             path, file_kind(st.st_mode));
    return NULL;
}

/* What an empty section of this kind lacks, for the error message. */
static const char *section_needs(const char *name)
{
    if (!strncmp(name, "model:", 6))
        return "a model needs at least one of unit_id, kind, n, m, z, type1, chord, preload; "
               "without any the section would be ignored";
    if (!strncmp(name, "rtu:", 4))
        return "device is required";
    if (!strncmp(name, "link:", 5))
        return "type and device (serial) or usb (usb) are required";
    return "a section with no keys has no effect; remove it or add keys";
}

/* The keys of every section, for "did you mean" (keep in step with the
 * key_* parsers above; tests/daemon/test_conf.c checks each is accepted). */
static const char *const keys_daemon[] = { "state_dir", "snapshot_interval", "fsync", "max_models",
                                           "link_backoff_max", "user", NULL };
static const char *const keys_modbus[] = { "tcp_listen", "max_clients", "idle_timeout", "byte_timeout",
                                           "tcp_keepalive", "evict_idle", "float_word_order", "int32_word_order",
                                           "default_model", "coord_scale", "grid_rows", "grid_cols", NULL };
static const char *const keys_listen[] = { "address", "allow", "read_only", NULL };
static const char *const keys_rtu[] = { "device", "baud", "parity", "stop_bits", "read_only", "t35_us", "rs485",
                                        "rs485_rts", "rs485_rts_delay_us", "rs485_rts_on_send",
                                        "rs485_delay_before_send_ms", "rs485_delay_after_send_ms",
                                        "rs485_termination", "rs485_strict", NULL };
static const char *const keys_model[] = { "unit_id", "n", "m", "z", "type1", "chord", "write_protect", "preload",
                                          "removed", NULL };
static const char *const keys_link[] = { "type", "device", "baud", "usb", "rto_ms", "peer_timeout_ms", NULL };
static const char *const keys_metrics[] = { "listen", NULL };

static const struct {
    const char *name;   /* "daemon", or "rtu:" for [rtu:NAME] */
    const char *const *keys;
} sections[] = {
    { "daemon", keys_daemon }, { "modbus", keys_modbus }, { "metrics", keys_metrics }, { "listen:", keys_listen },
    { "rtu:", keys_rtu },      { "model:", keys_model },   { "link:", keys_link },
};

const char *const *conf_section_keys(const char *section)
{
    for (size_t k = 0; k < sizeof sections / sizeof sections[0]; k++) {
        size_t n = strlen(sections[k].name);
        if (sections[k].name[n - 1] == ':' ? !strncmp(section, sections[k].name, n) : !strcmp(section, sections[k].name))
            return sections[k].keys;
    }
    return NULL;
}

/* Edit distance with transpositions (optimal string alignment), case
 * folded; names longer than 40 characters are never close. */
static int distance(const char *a, const char *b)
{
    int d[42][42];
    int la = (int)strlen(a), lb = (int)strlen(b);
    if (la > 40 || lb > 40)
        return 99;
    for (int i = 0; i <= la; i++)
        d[i][0] = i;
    for (int j = 0; j <= lb; j++)
        d[0][j] = j;
    for (int i = 1; i <= la; i++)
        for (int j = 1; j <= lb; j++) {
            int ca = tolower((unsigned char)a[i - 1]), cb = tolower((unsigned char)b[j - 1]);
            int v = d[i - 1][j - 1] + (ca != cb);
            if (d[i - 1][j] + 1 < v)
                v = d[i - 1][j] + 1;
            if (d[i][j - 1] + 1 < v)
                v = d[i][j - 1] + 1;
            if (i > 1 && j > 1 && ca == tolower((unsigned char)b[j - 2]) && tolower((unsigned char)a[i - 2]) == cb &&
                d[i - 2][j - 2] + 1 < v)
                v = d[i - 2][j - 2] + 1;
            d[i][j] = v;
        }
    return d[la][lb];
}

/* Close enough to be a typo: one edit in a short name, two in a longer. */
static int close_to(const char *name, const char *key, int *best)
{
    int d = distance(name, key), lim = strlen(key) <= 4 ? 1 : 2;
    if (strlen(key) == 1 && strlen(name) == 1 && tolower((unsigned char)name[0]) != key[0])
        return 0; /* "x" is not a typo of "n" */
    if (d > lim || d >= *best)
        return 0;
    *best = d;
    return 1;
}

const char *conf_suggest_key(const char *section, const char *name, const char **where)
{
    const char *const *keys = conf_section_keys(section);
    const char *hit = NULL;
    int best = 99;
    *where = NULL;
    for (int k = 0; keys && keys[k]; k++)
        if (close_to(name, keys[k], &best))
            hit = keys[k];
    if (hit)
        return hit;
    /* A key of another section, written in the wrong one. */
    for (size_t s = 0; s < sizeof sections / sizeof sections[0]; s++) {
        if (sections[s].keys == keys)
            continue;
        for (int k = 0; sections[s].keys[k]; k++)
            if (!strcasecmp(name, sections[s].keys[k])) {
                *where = sections[s].name;
                return sections[s].keys[k];
            }
    }
    return NULL;
}

/* " (did you mean ...?)" for an unknown key or section, or "". */
static void suggest(const struct parse *p, char *out, size_t size)
{
    const char *where, *hit;
    int best = 99;
    out[0] = 0;
    if (!strcmp(p->err, "unknown key")) {
        hit = conf_suggest_key(p->sec, p->key, &where);
        if (hit && !where)
            snprintf(out, size, ": did you mean '%s'?", hit);
        else if (hit)
            snprintf(out, size, ": '%s' is a key of [%s%s]", hit, where,
                     where[strlen(where) - 1] == ':' ? "NAME" : "");
        else if (conf_section_keys(p->sec))
            snprintf(out, size, " in this section (docs/daemon.md lists the keys)");
    } else if (!strcmp(p->err, "unknown section")) {
        char kind[64];
        const char *colon = strchr(p->sec, ':');
        snprintf(kind, sizeof kind, "%.*s", colon ? (int)(colon - p->sec + 1) : (int)strlen(p->sec), p->sec);
        hit = NULL;
        for (size_t s = 0; s < sizeof sections / sizeof sections[0]; s++)
            if (close_to(kind, sections[s].name, &best))
                hit = sections[s].name;
        if (hit && hit[strlen(hit) - 1] == ':')
            snprintf(out, size, ": did you mean [%s%s]?", hit, colon ? colon + 1 : "NAME");
        else if (hit)
            snprintf(out, size, ": did you mean [%s]?", hit);
        else
            snprintf(out, size, " (known: [daemon], [modbus], [metrics], [listen:NAME], [rtu:NAME], [model:ID], "
                     "[link:NAME])");
    }
}

int conf_default_unit(const struct conf *c)
{
    if (c->default_model == CONF_DEFAULT_NONE || (c->default_model == CONF_DEFAULT_AUTO && c->nmodels != 1))
        return 0;
    for (int k = 0; k < c->nmodels; k++)
        if (c->default_model == CONF_DEFAULT_AUTO || c->model[k].id == c->default_model)
            return c->model[k].unit;
    return 0;
}

int conf_check_hosts(const struct conf *c, const char *path, char *err, size_t errsize)
{
    for (int k = 0; k < c->nlisten; k++) {
        const struct conf_listen *l = &c->listen[k];
        struct addrinfo hints, *res = NULL;
        int rc;
        if (!l->host[0])
            continue;
        memset(&hints, 0, sizeof hints);
        hints.ai_family = AF_UNSPEC;
        hints.ai_socktype = SOCK_STREAM;
        hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
        rc = getaddrinfo(l->host, l->port, &hints, &res);
        if (res)
            freeaddrinfo(res);
        if (rc) {
            snprintf(err, errsize, "%s:%d: [%s%s] %s: cannot resolve host '%s': %s", path ? path : "built-in",
                     l->line, l->name[0] ? "listen:" : "modbus", l->name, l->name[0] ? "address" : "tcp_listen",
                     l->host, rc == EAI_SYSTEM ? strerror(errno) : gai_strerror(rc));
            return -1;
        }
    }
    if (c->metrics.port[0] && c->metrics.host[0]) {
        struct addrinfo hints, *res = NULL;
        int rc;
        memset(&hints, 0, sizeof hints);
        hints.ai_family = AF_UNSPEC;
        hints.ai_socktype = SOCK_STREAM;
        hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
        rc = getaddrinfo(c->metrics.host, c->metrics.port, &hints, &res);
        if (res)
            freeaddrinfo(res);
        if (rc) {
            snprintf(err, errsize, "%s:%d: [metrics] listen: cannot resolve host '%s': %s",
                     path && c->metrics.line ? path : "--metrics", c->metrics.line, c->metrics.host,
                     rc == EAI_SYSTEM ? strerror(errno) : gai_strerror(rc));
            return -1;
        }
    }
    return 0;
}

/* Lines of text up to its end (the number of the last line). */
static int count_lines(const char *text, size_t len)
{
    int n = 1;
    for (size_t k = 0; k + 1 < len; k++)
        n += text[k] == '\n';
    return n;
}

int conf_load(struct conf *c, const char *path, char *err, size_t errsize)
{
    struct parse *p;
    size_t len;
    char *text = read_conf(path, &len, err, errsize);
    int rc, vline = 0;
    if (!text)
        return -1;
    /* What a rewrite that is not atomic leaves behind (an editor crash, a
     * copy cut short, a reload between truncate and write): an empty file
     * would load as the built-in default, and a file cut mid-line may still
     * parse ("n = 12" cut to "n = 1"); both are refused before parsing. */
    if (len == 0) {
        snprintf(err, errsize, "%s: empty file (0 bytes): refused, a configuration sets at least one key (for the "
                 "built-in default run it2nd without -c)", path);
        free(text);
        return -1;
    }
    if (text[len - 1] != '\n') {
        snprintf(err, errsize, "%s:%d: no newline at the end of the last line: the file looks cut short (an "
                 "unfinished or interrupted rewrite); if it is complete, end it with a newline",
                 path, count_lines(text, len));
        free(text);
        return -1;
    }
    p = calloc(1, sizeof *p);
    if (!p) {
        snprintf(err, errsize, "%s: out of memory", path);
        free(text);
        return -1;
    }
    p->c = *c;
    p->text = text;
    p->len = len;
    rc = ini_parse_stream(reader, p, handler, p);
    if (rc == -2) {
        snprintf(err, errsize, "%s: out of memory", path);
    } else if (p->empty_line && (!p->err[0] || p->empty_line < p->err_line) && (rc <= 0 || p->empty_line < rc) &&
               (!p->bad_line || p->empty_line < p->bad_line)) {
        snprintf(err, errsize, "%s:%d: [%s]: empty section: its required keys are missing (%s)", path,
                 p->empty_line, p->empty_name, section_needs(p->empty_name));
        rc = 1;
    } else if (p->err[0] && (rc <= 0 || p->err_line <= rc)) {
        /* The first error in the file: ours (a key) before any syntax error. */
        char hint[160];
        suggest(p, hint, sizeof hint);
        if (p->syntax)
            snprintf(err, errsize, "%s:%d: syntax error: %s", path, p->err_line, p->err);
        else
            snprintf(err, errsize, "%s:%d: [%s] %s: %s%s", path, p->err_line, p->sec, p->key, p->err, hint);
        rc = 1;
    } else if (rc > 0 && rc == p->noeq_line) {
        char word[64];
        const char *const *keys = conf_section_keys(p->noeq_sec);
        int known = 0;
        snprintf(word, sizeof word, "%.*s", (int)strcspn(p->noeq_text, " \t"), p->noeq_text);
        for (int k = 0; keys && keys[k]; k++)
            known |= !strcmp(word, keys[k]);
        snprintf(err, errsize, "%s:%d: [%s] '%s': no '=' in this line: expected key = value%s%s%s", path, rc,
                 p->noeq_sec[0] ? p->noeq_sec : "(no section)", p->noeq_text, known ? " (" : "",
                 known ? word : "", known ? " = ...?)" : "");
    } else if (rc > 0) {
        snprintf(err, errsize, "%s:%d: syntax error", path, rc);
    } else if (p->bad_line) {
        if (strcmp(p->bad_why, "out of memory"))
            snprintf(err, errsize, "%s:%d: %s (at most %d characters)", path, p->bad_line, p->bad_why, p->maxline);
        else
            snprintf(err, errsize, "%s:%d: out of memory", path, p->bad_line);
        rc = 1;
    } else if (!p->nkeys) {
        snprintf(err, errsize, "%s:1: no key in the file (only blank lines and comments): refused, a configuration "
                 "sets at least one key (for the built-in default run it2nd without -c)", path);
        rc = 1;
    } else if (split_removed(p, &vline, p->sec, sizeof p->sec, p->key, sizeof p->key, p->err, sizeof p->err) ||
               validate(p, &vline, p->sec, sizeof p->sec, p->key, sizeof p->key, p->err, sizeof p->err)) {
        if (vline)
            snprintf(err, errsize, "%s:%d: [%s] %s: %s", path, vline, p->sec, p->key, p->err);
        else
            snprintf(err, errsize, "%s: [%s] %s: %s", path, p->sec, p->key, p->err);
        rc = 1;
    } else {
        *c = p->c;
    }
    free(text);
    free(p->lbuf);
    free(p->seen);
    free(p);
    return rc == 0 ? 0 : -1;
}

int conf_removes(const struct conf *c, int id)
{
    for (int k = 0; k < c->nremoved; k++)
        if (c->removed[k] == id)
            return 1;
    return 0;
}

/* Two paths naming one device: the same file (a symlink, a hard link) or
 * two nodes of one character device. Paths that cannot be stat'ed (not
 * plugged in yet) never conflict here. */
static int same_device(const struct dev_ref *x, const struct dev_ref *y)
{
    struct stat a, b;
    if (stat(x->device, &a) || stat(y->device, &b))
        return 0;
    return (a.st_dev == b.st_dev && a.st_ino == b.st_ino) ||
           (S_ISCHR(a.st_mode) && S_ISCHR(b.st_mode) && a.st_rdev == b.st_rdev);
}

int conf_check_devices(const struct conf *c, const char *path, char *err, size_t errsize)
{
    struct dev_ref d[CONF_MAX_RTU + CONF_MAX_LINKS];
    int n = device_refs(c, d), a = 0, b = 0;
    char real[PATH_MAX];
    if (first_conflict(d, n, same_device, &a, &b))
        return 0;
    if (!realpath(d[b].device, real))
        snprintf(real, sizeof real, "?");
    snprintf(err, errsize, "%s:%d: [%s:%s] device: %s is the same device as %s of [%s:%s] (line %d), both %s: "
             DEV_CONFLICT_WHY, path ? path : "built-in", d[b].line, d[b].kind, d[b].name, d[b].device, d[a].device,
             d[a].kind, d[a].name, d[a].line, real);
    return -1;
}

/* "[v6]:port" or "host:port" of a listener, for messages. */
static const char *addr_text(const char *host, const char *port, char *buf, size_t size)
{
    int v6 = strchr(host, ':') != NULL;
    snprintf(buf, size, "%s%s%s:%s", v6 ? "[" : "", host, v6 ? "]" : "", port);
    return buf;
}

int conf_apply_override(struct conf *c, const struct conf_override *o, char *err, size_t errsize)
{
    struct conf *n = malloc(sizeof *n);
    char a[96];
    if (!n) {
        snprintf(err, errsize, "out of memory");
        return -1;
    }
    *n = *c;
    if (o->nlisten > 0) {
        n->nlisten = 0;
        for (int k = 0; k < o->nlisten && k < CONF_MAX_LISTEN; k++) {
            struct conf_listen *l = &n->listen[n->nlisten];
            int rc;
            memset(l, 0, sizeof *l);
            rc = parse_listen(o->listen[k], l);
            if (rc) {
                snprintf(err, errsize, "--listen '%s': %s", o->listen[k],
                         rc == -2 ? "port 0: expected a port 1..65535" : "expected HOST:PORT, [V6ADDR]:PORT or :PORT");
                goto fail;
            }
            for (int j = 0; j < n->nlisten; j++)
                if (!strcmp(n->listen[j].host, l->host) && !strcmp(n->listen[j].port, l->port)) {
                    snprintf(err, errsize, "--listen '%s': given twice", o->listen[k]);
                    goto fail;
                }
            n->nlisten++;
        }
    }
    if (o->state_dir && copy_str(n->state_dir, sizeof n->state_dir, o->state_dir)) {
        snprintf(err, errsize, "--state-dir '%s': path empty or longer than %d bytes", o->state_dir, CONF_PATH - 1);
        goto fail;
    }
    if (o->metrics && !strcasecmp(o->metrics, "none")) {
        memset(&n->metrics, 0, sizeof n->metrics);
    } else if (o->metrics) {
        struct conf_listen l;
        int rc;
        memset(&l, 0, sizeof l);
        rc = parse_listen(o->metrics, &l);
        if (rc) {
            snprintf(err, errsize, "--metrics '%s': %s", o->metrics,
                     rc == -2 ? "port 0: expected a port 1..65535" : "expected HOST:PORT, [V6ADDR]:PORT, :PORT or none");
            goto fail;
        }
        memcpy(n->metrics.host, l.host, sizeof n->metrics.host);
        memcpy(n->metrics.port, l.port, sizeof n->metrics.port);
        n->metrics.line = 0;
    }
    for (int k = 0; k < n->nlisten && n->metrics.port[0]; k++)
        if (!strcmp(n->listen[k].host, n->metrics.host) && !strcmp(n->listen[k].port, n->metrics.port)) {
            snprintf(err, errsize, "%s: the metrics endpoint and a Modbus listener on one address; give --metrics "
                     "(or [metrics] listen) a port of its own", addr_text(n->metrics.host, n->metrics.port, a, sizeof a));
            goto fail;
        }
    *c = *n;
    free(n);
    return 0;
fail:
    free(n);
    return -1;
}
