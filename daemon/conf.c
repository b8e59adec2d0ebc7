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
#include "conf_schema.h"
#include "it2n.h"
#include "it2n_regmap.h"

/* Where a section's settings came from, for cross-key errors: its first
 * key and the line of each of its keys (0: not in the file), indexed as
 * the section's keys in the schema. */
struct origin {
    int first_line; /* its first key */
    char first_key[CONF_NAME];
    int line[CONF_SCHEMA_MAX_KEYS];
};

/* Longest line kept whole (libinih's own limit, INI_MAX_LINE, is 200):
 * an empty section's error quotes its header's name in full. */
#define CONF_LINE_CAP 256

struct parse {
    struct conf c;
    int listen_set; /* first tcp_listen replaces the default */
    int models_set; /* first [model:N] replaces the default */
    char err[256];
    char sec[64], key[64];     /* where the first error was raised */
    char value[CONF_LINE_CAP]; /* the value refused, for "did you mean" */
    const struct conf_key *err_key;
    int err_line, syntax;
    /* Lines are counted here (the reader), not by libinih, so a message
     * always names the physical line. */
    const char *text; /* the whole file, read by read_conf     */
    size_t len, pos;
    char *lbuf;
    size_t lcap;
    int line, bad_line, maxline;
    int nkeys; /* keys in the whole file                 */
    /* The first line that is neither blank, a comment, a header nor a
     * "key = value" (libinih calls it a syntax error, without saying why). */
    int noeq_line;
    char noeq_text[64], noeq_sec[64];
    const char *bad_why;
    /* The section being read: its header line and name, and whether a key
     * of it was seen (an empty section is an error: its keys are missing). */
    int sec_line, sec_keys;
    char sec_name[CONF_LINE_CAP]; /* whole: reader() refuses longer lines */
    int empty_line;               /* first empty section's header line     */
    char empty_name[CONF_LINE_CAP];
    /* Origins: one per section of a single kind (by enum conf_sec), one
     * per instance of the named kinds. */
    struct origin single[CONF_SEC_METRICS + 1];
    struct origin model[CONF_MAX_MODELS], rtu[CONF_MAX_RTU], link[CONF_MAX_LINKS], listen[CONF_MAX_LISTEN];
    /* Every (section, key) set so far, for duplicate keys (heap, freed
     * with the parse). */
    /* clang-format off */
    struct seen_key { char sec[64], key[64]; int line; } *seen;
    /* clang-format on */
    int nseen, cap_seen;
};

/* A key given twice in one section (or in two sections of the same name)
 * would silently take the last value: an error naming the first line.
 * Keys the schema marks repeatable add up instead. Returns that first
 * line. */
static int duplicate_key(struct parse *p, const char *section, const char *name)
{
    for (int k = 0; k < p->nseen; k++)
        if (!strcmp(p->seen[k].sec, section) && !strcmp(p->seen[k].key, name))
            return p->seen[k].line;
    if (p->nseen == p->cap_seen) {
        int cap = p->cap_seen ? 2 * p->cap_seen : 64;
        struct seen_key *s = realloc(p->seen, (size_t)cap * sizeof *s);
        if (!s)
            return 0; /* no memory: the check is skipped, nothing breaks */
        p->seen = s;
        p->cap_seen = cap;
    }
    snprintf(p->seen[p->nseen].sec, sizeof p->seen[p->nseen].sec, "%s", section);
    snprintf(p->seen[p->nseen].key, sizeof p->seen[p->nseen].key, "%s", name);
    p->seen[p->nseen++].line = p->line;
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
    if (conf_schema_int(colon + 1, 0, 65535, &port))
        return -1;
    if (port == 0)
        return -2; /* the kernel would pick a port no client knows */
    snprintf(l->port, sizeof l->port, "%d", port);
    return 0;
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

#define FAIL(...)                                     \
    do {                                              \
        snprintf(p->err, sizeof p->err, __VA_ARGS__); \
        p->err_line = p->line;                        \
        return 0;                                     \
    } while (0)
#define WHY(...)                             \
    do {                                     \
        snprintf(why, whysize, __VA_ARGS__); \
        return -1;                           \
    } while (0)
#define PORT0_WHY "port 0: expected a port 1..65535 (0 would be a random port no client knows)"

/* The values of the compound types (a listener, an allow-list, ...) into
 * their section's struct at base. 0, or -1 with the reason in why. */
static int set_compound(struct parse *p, void *base, const struct conf_key *k, const char *v, int line, char *why,
                        size_t whysize)
{
    int rc;
    switch (k->type) {
    case CONF_T_LISTEN: { /* [modbus] tcp_listen: one more listener */
        struct conf *c = base;
        if (p && !p->listen_set) { /* the file's first replaces the default */
            c->nlisten = 0;
            p->listen_set = 1;
        }
        if (!strcasecmp(v, "none"))
            return 0;
        if (c->nlisten == CONF_MAX_LISTEN)
            WHY("more than %d listen addresses", CONF_MAX_LISTEN);
        memset(&c->listen[c->nlisten], 0, sizeof c->listen[c->nlisten]);
        rc = parse_listen(v, &c->listen[c->nlisten]);
        if (rc == -2)
            WHY(PORT0_WHY);
        if (rc)
            WHY("expected host:port, [v6addr]:port or :port");
        c->listen[c->nlisten++].line = line;
        return 0;
    }
    case CONF_T_ADDR: { /* [listen:NAME] address */
        struct conf_listen *l = base;
        char nm[CONF_NAME];
        memcpy(nm, l->name, sizeof nm);
        rc = parse_listen(v, l);
        memcpy(l->name, nm, sizeof nm);
        if (rc == -2)
            WHY(PORT0_WHY);
        if (rc)
            WHY("expected host:port, [v6addr]:port or :port");
        l->line = line;
        return 0;
    }
    case CONF_T_ENDPOINT: { /* [metrics] listen */
        struct conf_metrics *m = base;
        struct conf_listen l;
        memset(&l, 0, sizeof l);
        if (!strcasecmp(v, "none")) {
            memset(m, 0, sizeof *m);
            return 0;
        }
        rc = parse_listen(v, &l);
        if (rc == -2)
            WHY("port 0: expected a port 1..65535 (Prometheus must know where to scrape)");
        if (rc)
            WHY("expected host:port, [v6addr]:port, :port or none");
        memcpy(m->host, l.host, sizeof m->host);
        memcpy(m->port, l.port, sizeof m->port);
        return 0;
    }
    case CONF_T_ALLOW: {
        struct conf_listen *l = base;
        char buf[256], *tok, *save = NULL, reason[160];
        snprintf(buf, sizeof buf, "%s", v);
        if (!v[strspn(v, ", \t")]) /* "allow =" must not read as "everyone" */
            WHY("expected IPv4/IPv6 addresses or prefixes");
        for (tok = strtok_r(buf, ", \t", &save); tok; tok = strtok_r(NULL, ", \t", &save)) {
            if (l->nallow == CONF_MAX_ALLOW)
                WHY("more than %d allow entries in this section", CONF_MAX_ALLOW);
            if (acl_parse_prefix(tok, &l->allow[l->nallow], reason, sizeof reason))
                WHY("%s", reason);
            l->nallow++;
        }
        return 0;
    }
    case CONF_T_USB:
        if (parse_usb(v, base))
            WHY("expected VID:PID[:serial] in hex");
        return 0;
    case CONF_T_USER: {
        /* Resolved now, so a typo is a config error with file:line rather
         * than a failure after the sockets are open. */
        struct conf *c = base;
        const struct passwd *pw = getpwnam(v);
        if (copy_str(c->user, sizeof c->user, v))
            WHY("name empty or too long");
        if (!pw)
            WHY("unknown user '%s'", v);
        c->uid = (unsigned)pw->pw_uid;
        c->gid = (unsigned)pw->pw_gid;
        return 0;
    }
    case CONF_T_BROKER:
        if (spb_conf_parse_broker(base, v))
            WHY("expected host:port, [v6addr]:port or host (port 1883)");
        return 0;
    case CONF_T_SECRET: return spb_conf_read_password(base, v, why, whysize);
    default: WHY("(no parser for this key's type)");
    }
}

/* Store value v of key k into its section's struct at base: the one way
 * every key of every section is read (and every default set: dflt, then
 * nothing is checked against the system and no line is kept). p is the
 * file's parse, NULL for a single key (conf_key). 0, or -1 with the
 * reason in why. */
static int set_value(struct parse *p, int dflt, const struct conf_section *s, void *base, const struct conf_key *k,
                     const char *v, int line, char *why, size_t whysize)
{
    char *at = (char *)base + k->off;
    long x;
    switch (k->type) {
    case CONF_T_INT:
    case CONF_T_ENUM:
    case CONF_T_BOOL:
    case CONF_T_FLAG:
        if (conf_schema_number(k, v, &x)) {
            conf_schema_expect(k, why, whysize);
            return -1;
        }
        if (k->type == CONF_T_FLAG) {
            unsigned *u = (unsigned *)(void *)at;
            *u = x ? (*u | k->bit) : (*u & ~k->bit);
        } else if (k->size == sizeof(char)) {
            *at = (char)x;
        } else {
            *(int *)(void *)at = (int)x;
        }
        break;
    case CONF_T_STR:
    case CONF_T_SPB_ID:
        if (k->type == CONF_T_SPB_ID ? !spb_conf_valid_id(v) : copy_str(at, k->size, v))
            WHY(k->type == CONF_T_SPB_ID ? "expected 1..%zu printable ASCII characters without '/', '+', '#' or blanks"
                                         : "expected 1..%zu characters",
                k->size - 1);
        snprintf(at, k->size, "%s", v);
        break;
    case CONF_T_PATH:
    case CONF_T_FILE:
        if (copy_str(at, k->size, v))
            WHY("path empty or too long");
        if (k->type == CONF_T_FILE && !dflt) {
            /* Readable now (what it holds is checked later, e.g. by
             * spb_tls_check). */
            FILE *f = fopen(v, "r");
            if (!f)
                WHY("cannot open '%s': %s", v, strerror(errno));
            fclose(f);
        }
        break;
    default:
        if (set_compound(p, base, k, v, line, why, whysize))
            return -1;
        break;
    }
    if (dflt)
        return 0;
    if (k->line_off)
        *(int *)(void *)((char *)base + k->line_off - 1) = line;
    if (k->set && s->set_off)
        *(unsigned *)(void *)((char *)base + s->set_off - 1) |= k->set;
    return 0;
}

/* A new section instance (or the whole conf for the single kinds) gets
 * each key's default from the schema. */
static void set_defaults(const struct conf_section *s, void *base)
{
    char why[160];
    for (int k = 0; k < s->nkeys; k++) {
        const struct conf_key *key = &s->keys[k];
        if (key->def)
            set_value(NULL, 1, s, base, key, key->def, 0, why, sizeof why);
        else if (key->unset && (key->type == CONF_T_INT || key->type == CONF_T_ENUM || key->type == CONF_T_BOOL))
            *(int *)(void *)((char *)base + key->off) = key->unset;
    }
}

static const struct conf_section *section_of(enum conf_sec id)
{
    int n;
    const struct conf_section *s = conf_schema_sections(&n);
    for (int k = 0; k < n; k++)
        if (s[k].id == id)
            return &s[k];
    return NULL;
}

/* The line of key `name` in a section with origin o (0: not given). */
static int key_line(const struct origin *o, enum conf_sec id, const char *name)
{
    int idx = 0;
    if (!conf_schema_key(section_of(id), name, &idx))
        return 0;
    return o->line[idx];
}

_Static_assert(offsetof(struct conf_listen, name) == 0 && offsetof(struct conf_rtu, name) == 0 &&
                   offsetof(struct conf_link, name) == 0,
               "named() finds an instance by the name it starts with");

/* Index of the named instance `name` in names[0..*n) (a stride of `size`
 * bytes), created with its defaults if new; -1 with p->err when full. */
static int named(struct parse *p, const struct conf_section *s, void *array, size_t size, int *n, int max,
                 const char *name, struct origin *org)
{
    char *a = array;
    int k;
    for (k = 0; k < *n; k++)
        if (!strcmp(a + (size_t)k * size, name)) /* each struct starts with its name */
            return k;
    if (k == max) {
        snprintf(p->err, sizeof p->err, "more than %d [%s%s] sections", max, s->name, s->arg);
        p->err_line = p->line;
        return -1;
    }
    memset(a + (size_t)k * size, 0, size);
    if (copy_str(a + (size_t)k * size, CONF_NAME, name)) {
        snprintf(p->err, sizeof p->err, "section name too long");
        p->err_line = p->line;
        return -1;
    }
    memset(&org[k], 0, sizeof org[k]);
    set_defaults(s, a + (size_t)k * size);
    (*n)++;
    return k;
}

/* A key of [sparkplug]: the section is given (its first key is where
 * spb_conf_check names a missing one). */
static void spb_opened(struct spb_conf *spb, int line, const char *name)
{
    if (!spb->enabled) {
        spb->enabled = 1;
        spb->first_line = line;
        snprintf(spb->first_key, sizeof spb->first_key, "%.*s", (int)sizeof spb->first_key - 1, name);
    }
}

/* The struct the keys of section `section` (of kind s) go to, and its
 * origin; NULL with p->err set when the section cannot be had. */
static void *instance(struct parse *p, const struct conf_section *s, const char *section, struct origin **o)
{
    struct conf *c = &p->c;
    const char *arg = section + strlen(s->name);
    int k, id;
    switch (s->id) {
    case CONF_SEC_LISTEN:
        if (!p->listen_set) { /* the first [listen:] replaces the default */
            c->nlisten = 0;
            p->listen_set = 1;
        }
        k = named(p, s, c->listen, sizeof c->listen[0], &c->nlisten, CONF_MAX_LISTEN, arg, p->listen);
        if (k < 0)
            return NULL;
        *o = &p->listen[k];
        return &c->listen[k];
    case CONF_SEC_RTU:
        if ((k = named(p, s, c->rtu, sizeof c->rtu[0], &c->nrtu, CONF_MAX_RTU, arg, p->rtu)) < 0)
            return NULL;
        *o = &p->rtu[k];
        return &c->rtu[k];
    case CONF_SEC_LINK:
        if ((k = named(p, s, c->link, sizeof c->link[0], &c->nlinks, CONF_MAX_LINKS, arg, p->link)) < 0)
            return NULL;
        *o = &p->link[k];
        return &c->link[k];
    case CONF_SEC_MODEL:
        if (conf_schema_int(arg, 0, 254, &id)) {
            snprintf(p->err, sizeof p->err, "model section must be [model:ID], ID 0..254 (the model id on the links)");
            p->err_line = p->line;
            return NULL;
        }
        if (!p->models_set) { /* the first [model:] replaces the default */
            c->nmodels = 0;
            p->models_set = 1;
        }
        for (k = 0; k < c->nmodels && c->model[k].id != id; k++)
            ;
        if (k == c->nmodels) {
            if (k == CONF_MAX_MODELS) {
                snprintf(p->err, sizeof p->err, "more than %d models", CONF_MAX_MODELS);
                p->err_line = p->line;
                return NULL;
            }
            memset(&c->model[k], 0, sizeof c->model[k]);
            memset(&p->model[k], 0, sizeof p->model[k]);
            set_defaults(s, &c->model[k]);
            c->model[k].id = id;
            c->model[k].unit = id >= 1 && id <= 247 ? id : 0;
            c->nmodels++;
        }
        *o = &p->model[k];
        return &c->model[k];
    case CONF_SEC_SPARKPLUG:
        spb_opened(&c->spb, p->line, p->key);
        *o = &p->single[s->id];
        return &c->spb;
    case CONF_SEC_METRICS: *o = &p->single[s->id]; return &c->metrics;
    default: /* [daemon], [modbus]: fields of struct conf itself */ *o = &p->single[s->id]; return c;
    }
}

/* One "key = value" of the file: through the schema into the conf. */
static int handler(void *user, const char *section, const char *name, const char *value)
{
    struct parse *p = user;
    const struct conf_section *s;
    const struct conf_key *k;
    struct origin *o = NULL;
    char why[200];
    void *base;
    int idx = 0;
    if (!name) /* section start without keys (INI_CALL_HANDLER_ON_NEW_SECTION) */
        return 1;
    if (p->err[0]) /* libinih goes on after an error: keep the first */
        return 1;
    if (!name[0]) { /* " = value": libinih passes an empty name */
        p->syntax = 1;
        FAIL("key name missing before '='");
    }
    snprintf(p->sec, sizeof p->sec, "%s", section);
    snprintf(p->key, sizeof p->key, "%s", name);
    p->sec_keys++;
    p->nkeys++;
    s = conf_schema_section(section);
    k = conf_schema_key(s, name, &idx);
    if (!k || !(k->flags & CONF_K_REPEAT)) {
        int first = duplicate_key(p, section, name);
        if (first)
            FAIL("duplicate key (first set on line %d)", first);
    }
    if (!s)
        FAIL("unknown section");
    if (!(base = instance(p, s, section, &o)))
        return 0;
    if (!k)
        FAIL("unknown key");
    if (!o->first_line) {
        o->first_line = p->line;
        snprintf(o->first_key, sizeof o->first_key, "%s", name);
    }
    if (set_value(p, 0, s, base, k, value, p->line, why, sizeof why)) {
        p->err_key = k; /* libinih's buffer is gone when the error is reported */
        snprintf(p->value, sizeof p->value, "%s", value);
        FAIL("%s", why);
    }
    o->line[idx] = p->line;
    return 1;
}

void conf_default(struct conf *c)
{
    memset(c, 0, sizeof *c);
    spb_conf_default(&c->spb);
    /* Every key's default is the schema's (the single sections' keys are
     * fields of struct conf, [sparkplug]'s of c->spb). */
    set_defaults(section_of(CONF_SEC_DAEMON), c);
    set_defaults(section_of(CONF_SEC_MODBUS), c);
    set_defaults(section_of(CONF_SEC_SPARKPLUG), &c->spb);
    set_defaults(section_of(CONF_SEC_METRICS), &c->metrics);
    /* Without any [model:] section: model 1 on unit 1 with the paper's
     * data set. */
    set_defaults(section_of(CONF_SEC_MODEL), &c->model[0]);
    c->model[0].id = 1;
    c->model[0].unit = 1;
    c->model[0].preload = 1;
    c->nmodels = 1;
}

/* Cross-key checks, done after the whole file is read. Each error names
 * the line of a key involved (or, for a missing key, the section's first
 * key): *line and *key are set, err gets "[section] key: reason". */
#define VFAIL(l, sec, k, ...)                  \
    do {                                       \
        *line = (l);                           \
        snprintf(key, keysize, "%s", (k));     \
        snprintf(sect, sectsize, "%s", (sec)); \
        snprintf(err, errsize, __VA_ARGS__);   \
        return -1;                             \
    } while (0)

/* [model:ID] sections with removed = yes leave the model list (their
 * unit id is free, they do not count in max_models) for conf.removed, the
 * operator's consent to discard what the state holds for them. Their
 * origins move with the models, so later errors name the right lines. */
static int split_removed(struct parse *p, int *line, char *sect, size_t sectsize, char *key, size_t keysize, char *err,
                         size_t errsize)
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
        VFAIL(key_line(&p->model[last], CONF_SEC_MODEL, "removed"), sec, "removed",
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
            d[n++] = (struct dev_ref){"rtu", c->rtu[k].name, c->rtu[k].device, c->rtu[k].device_line};
    for (int k = 0; k < c->nlinks; k++)
        if (c->link[k].type == CONF_LINK_SERIAL && c->link[k].device[0])
            d[n++] = (struct dev_ref){"link", c->link[k].name, c->link[k].device, c->link[k].device_line};
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

/* The first key of section id marked CONF_K_REQUIRED that origin o lacks,
 * or NULL. */
static const char *missing_key(const struct origin *o, enum conf_sec id)
{
    const struct conf_section *s = section_of(id);
    for (int k = 0; k < s->nkeys; k++)
        if ((s->keys[k].flags & CONF_K_REQUIRED) && !o->line[k])
            return s->keys[k].name;
    return NULL;
}

/* The key of section id with flag `flag` given first in the file (its line
 * in *line), or NULL. */
static const char *first_flagged(const struct origin *o, enum conf_sec id, unsigned flag, int *line)
{
    const struct conf_section *s = section_of(id);
    const char *name = NULL;
    *line = 0;
    for (int k = 0; k < s->nkeys; k++)
        if ((s->keys[k].flags & flag) && o->line[k] && (!*line || o->line[k] < *line)) {
            *line = o->line[k];
            name = s->keys[k].name;
        }
    return name;
}

static int validate(const struct parse *p, int *line, char *sect, size_t sectsize, char *key, size_t keysize, char *err,
                    size_t errsize)
{
    const struct conf *c = &p->c;
    const char *req;
    char sec[64];
    const struct origin *dm = &p->single[CONF_SEC_MODBUS];
    int max_models_line = key_line(&p->single[CONF_SEC_DAEMON], CONF_SEC_DAEMON, "max_models");
    int rows_line = key_line(dm, CONF_SEC_MODBUS, "grid_rows"), cols_line = key_line(dm, CONF_SEC_MODBUS, "grid_cols");
    if (c->default_model >= 0) {
        int k = 0;
        while (k < c->nmodels && c->model[k].id != c->default_model)
            k++;
        if (k == c->nmodels)
            VFAIL(key_line(dm, CONF_SEC_MODBUS, "default_model"), "modbus", "default_model",
                  "no [model:%d] is configured", c->default_model);
    }
    if (c->nmodels > c->max_models) {
        const struct origin *o = &p->model[c->max_models];
        snprintf(sec, sizeof sec, "model:%d", c->model[c->max_models].id);
        if (max_models_line)
            VFAIL(max_models_line > o->first_line ? max_models_line : o->first_line, "daemon", "max_models",
                  "%d models configured, limit %d", c->nmodels, c->max_models);
        VFAIL(o->first_line, sec, o->first_key,
              "model %d of at most max_models = %d (the default; set max_models in [daemon])", c->max_models + 1,
              c->max_models);
    }
    if (c->grid_rows * c->grid_cols > (int)IT2N_REGMAP_GRID_MAX_NODES)
        VFAIL(rows_line > cols_line ? rows_line : cols_line, "modbus",
              rows_line > cols_line ? "grid_rows" : "grid_cols", "grid_rows x grid_cols = %d x %d exceeds %u nodes",
              c->grid_rows, c->grid_cols, IT2N_REGMAP_GRID_MAX_NODES);
    for (int k = 0; k < c->nmodels; k++) {
        const struct conf_model *m = &c->model[k];
        const struct origin *o = &p->model[k];
        int unit_line = key_line(o, CONF_SEC_MODEL, "unit_id"), preload_line = key_line(o, CONF_SEC_MODEL, "preload");
        int chord_line = key_line(o, CONF_SEC_MODEL, "chord"), kind_line = key_line(o, CONF_SEC_MODEL, "kind");
        snprintf(sec, sizeof sec, "model:%d", m->id);
        if (m->unit < 1)
            VFAIL(o->first_line, sec, o->first_key, "unit_id is required for model ids 0 and above 247");
        for (int l = 0; l < k; l++)
            if (c->model[l].unit == m->unit) {
                int other = key_line(&p->model[l], CONF_SEC_MODEL, "unit_id");
                if (unit_line)
                    VFAIL(unit_line, sec, "unit_id", "%d already used by model %d", m->unit, c->model[l].id);
                VFAIL(other ? other : o->first_line, sec, other ? "unit_id" : o->first_key,
                      "unit id %d (the model id) already used by model %d", m->unit, c->model[l].id);
            }
        if (m->kind == CONF_KIND_BEZIER && (m->n > IT2N_MAX_DEGREE || m->m > IT2N_MAX_DEGREE)) {
            int ln = key_line(o, CONF_SEC_MODEL, m->n > IT2N_MAX_DEGREE ? "n" : "m");
            VFAIL(ln, sec, m->n > IT2N_MAX_DEGREE ? "n" : "m",
                  "%d exceeds the bezier kind's degree limit %d; use 1..%d, or kind = bspline for grids up to %d",
                  m->n > IT2N_MAX_DEGREE ? m->n : m->m, IT2N_MAX_DEGREE, IT2N_MAX_DEGREE, IT2N_BSPLINE_MAX_N);
        }
        if (m->kind == CONF_KIND_BSPLINE && (m->flags & IT2N_F_CHORD))
            VFAIL(chord_line ? chord_line : kind_line, sec, chord_line ? "chord" : "kind",
                  "the bspline kind has uniform parameters only: chord = yes needs kind = bezier");
        if (m->preload && (m->n != 3 || m->m != 3 || (m->flags & (IT2N_F_Z | IT2N_F_TYPE1))))
            VFAIL(preload_line ? preload_line : o->first_line, sec, preload_line ? "preload" : o->first_key,
                  "the paper data set needs n = m = 3, no z, not type1");
    }
    for (int k = 0; k < c->nlisten; k++) {
        const struct conf_listen *l = &c->listen[k];
        if (!l->name[0])
            continue;
        snprintf(sec, sizeof sec, "listen:%s", l->name);
        if ((req = missing_key(&p->listen[k], CONF_SEC_LISTEN)) != NULL)
            VFAIL(p->listen[k].first_line, sec, p->listen[k].first_key, "%s is required in this section", req);
    }
    for (int k = 0; k < c->nlisten; k++)
        for (int j = 0; j < k; j++)
            if (!strcmp(c->listen[k].host, c->listen[j].host) && !strcmp(c->listen[k].port, c->listen[j].port)) {
                snprintf(sec, sizeof sec, "%s%s", c->listen[k].name[0] ? "listen:" : "modbus", c->listen[k].name);
                VFAIL(c->listen[k].line, sec, c->listen[k].name[0] ? "address" : "tcp_listen",
                      "%s%s%s:%s is already a listener address", strchr(c->listen[k].host, ':') ? "[" : "",
                      c->listen[k].host, strchr(c->listen[k].host, ':') ? "]" : "", c->listen[k].port);
            }
    for (int k = 0; k < c->nlisten && c->metrics.port[0]; k++)
        if (!strcmp(c->listen[k].host, c->metrics.host) && !strcmp(c->listen[k].port, c->metrics.port))
            VFAIL(c->metrics.line, "metrics", "listen",
                  "%s:%s is also a Modbus listener address (%s%.0d): "
                  "the metrics endpoint needs a port of its own",
                  c->metrics.host, c->metrics.port, c->listen[k].line ? "line " : "the built-in default",
                  c->listen[k].line);
    for (int k = 0; k < c->nrtu; k++) {
        const struct conf_rtu *r = &c->rtu[k];
        const struct origin *o = &p->rtu[k];
        const char *opt, *lib, *kern;
        int opt_line, lib_line, kern_line;
        snprintf(sec, sizeof sec, "rtu:%s", r->name);
        if ((req = missing_key(o, CONF_SEC_RTU)) != NULL)
            VFAIL(o->first_line, sec, o->first_key, "%s is required in this section", req);
        opt = first_flagged(o, CONF_SEC_RTU, CONF_K_RS485, &opt_line);
        lib = first_flagged(o, CONF_SEC_RTU, CONF_K_LIBMODBUS, &lib_line);
        kern = first_flagged(o, CONF_SEC_RTU, CONF_K_KERNEL, &kern_line);
        if (!r->rs485 && opt)
            VFAIL(opt_line, sec, opt, "needs rs485 = yes in this section");
        if (r->rts == CONF_RTS_NONE && lib)
            VFAIL(lib_line, sec, lib, "needs rs485_rts = up or down (libmodbus switching RTS)");
        if (r->rts != CONF_RTS_NONE && kern)
            VFAIL(kern_line, sec, kern,
                  "a kernel RS-485 option, but rs485_rts = %s (line %d) has libmodbus switch RTS instead; "
                  "use one or the other",
                  r->rts == CONF_RTS_UP ? "up" : "down", key_line(o, CONF_SEC_RTU, "rs485_rts"));
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
    if (c->spb.enabled && (req = missing_key(&p->single[CONF_SEC_SPARKPLUG], CONF_SEC_SPARKPLUG)) != NULL)
        VFAIL(c->spb.first_line, "sparkplug", c->spb.first_key, "%s is required in this section", req);
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
    p->maxline = num - 2;               /* room for the newline and the NUL */
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
    return S_ISDIR(mode)    ? "a directory"
           : S_ISFIFO(mode) ? "a FIFO"
           : S_ISCHR(mode)  ? "a character device"
           : S_ISBLK(mode)  ? "a block device"
           : S_ISSOCK(mode) ? "a socket"
                            : "not a regular file";
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
        snprintf(err, errsize,
                 "%s: changed while it was read (%lld bytes, then %zu%s): it is being rewritten; "
                 "reload once it is complete",
                 path, (long long)st.st_size, len, len > (size_t)st.st_size ? " or more" : "");
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
static const char *empty_needs(const char *name)
{
    const struct conf_section *s = conf_schema_section(name);
    return s ? s->needs : "a section with no keys has no effect; remove it or add keys";
}

/* " (did you mean ...?)" for an unknown key or section, or a bad value of
 * a key with listed values; or "". */
static void suggest(const struct parse *p, char *out, size_t size)
{
    const struct conf_section *s = conf_schema_section(p->sec), *where, *hit;
    const char *key;
    out[0] = 0;
    if (!strcmp(p->err, "unknown key")) {
        key = conf_schema_suggest_key(s, p->key, &where);
        if (key && !where)
            snprintf(out, size, ": did you mean '%s'?", key);
        else if (key)
            snprintf(out, size, ": '%s' is a key of [%s%s]", key, where->name, where->arg ? where->arg : "");
        else if (s)
            snprintf(out, size, " in this section (it2nd --config-keys lists the keys)");
    } else if (!strcmp(p->err, "unknown section")) {
        const char *colon = strchr(p->sec, ':');
        hit = conf_schema_suggest_section(p->sec);
        if (hit && hit->arg)
            snprintf(out, size, ": did you mean [%s%s]?", hit->name, colon && colon[1] ? colon + 1 : hit->arg);
        else if (hit)
            snprintf(out, size, ": did you mean [%s]?", hit->name);
        else {
            int n;
            const struct conf_section *all = conf_schema_sections(&n);
            snprintf(out, size, " (known:");
            for (int k = 0; k < n; k++) {
                size_t len = strlen(out);
                snprintf(out + len, size - len, "%s [%s%s]", k ? "," : "", all[k].name, all[k].arg ? all[k].arg : "");
            }
            snprintf(out + strlen(out), size - strlen(out), ")");
        }
    } else if (p->err_key && (key = conf_schema_suggest_word(p->err_key, p->value)) != NULL) {
        snprintf(out, size, ": did you mean '%s'?", key);
    }
}

int conf_key(void *base, const char *section, const char *name, const char *value, int line, char *err, size_t errsize)
{
    const struct conf_section *s = conf_schema_section(section);
    const struct conf_key *k = conf_schema_key(s, name, NULL);
    if (!s || !k) {
        snprintf(err, errsize, "unknown %s", s ? "key" : "section");
        return -1;
    }
    if (s->id == CONF_SEC_SPARKPLUG)
        spb_opened(base, line, name);
    return set_value(NULL, 0, s, base, k, value, line, err, errsize);
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
            snprintf(err, errsize, "%s:%d: [%s%s] %s: cannot resolve host '%s': %s", path ? path : "built-in", l->line,
                     l->name[0] ? "listen:" : "modbus", l->name, l->name[0] ? "address" : "tcp_listen", l->host,
                     rc == EAI_SYSTEM ? strerror(errno) : gai_strerror(rc));
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
        snprintf(err, errsize,
                 "%s: empty file (0 bytes): refused, a configuration sets at least one key (for the "
                 "built-in default run it2nd without -c)",
                 path);
        free(text);
        return -1;
    }
    if (text[len - 1] != '\n') {
        snprintf(err, errsize,
                 "%s:%d: no newline at the end of the last line: the file looks cut short (an "
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
        snprintf(err, errsize, "%s:%d: [%s]: empty section: its required keys are missing (%s)", path, p->empty_line,
                 p->empty_name, empty_needs(p->empty_name));
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
        int known;
        snprintf(word, sizeof word, "%.*s", (int)strcspn(p->noeq_text, " \t"), p->noeq_text);
        known = conf_schema_key(conf_schema_section(p->noeq_sec), word, NULL) != NULL;
        snprintf(err, errsize, "%s:%d: [%s] '%s': no '=' in this line: expected key = value%s%s%s", path, rc,
                 p->noeq_sec[0] ? p->noeq_sec : "(no section)", p->noeq_text, known ? " (" : "", known ? word : "",
                 known ? " = ...?)" : "");
    } else if (rc > 0) {
        snprintf(err, errsize, "%s:%d: syntax error", path, rc);
    } else if (p->bad_line) {
        if (strcmp(p->bad_why, "out of memory"))
            snprintf(err, errsize, "%s:%d: %s (at most %d characters)", path, p->bad_line, p->bad_why, p->maxline);
        else
            snprintf(err, errsize, "%s:%d: out of memory", path, p->bad_line);
        rc = 1;
    } else if (!p->nkeys) {
        snprintf(err, errsize,
                 "%s:1: no key in the file (only blank lines and comments): refused, a configuration "
                 "sets at least one key (for the built-in default run it2nd without -c)",
                 path);
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
    snprintf(err, errsize,
             "%s:%d: [%s:%s] device: %s is the same device as %s of [%s:%s] (line %d), both %s: " DEV_CONFLICT_WHY,
             path ? path : "built-in", d[b].line, d[b].kind, d[b].name, d[b].device, d[a].device, d[a].kind, d[a].name,
             d[a].line, real);
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
                     rc == -2 ? "port 0: expected a port 1..65535"
                              : "expected HOST:PORT, [V6ADDR]:PORT, :PORT or none");
            goto fail;
        }
        memcpy(n->metrics.host, l.host, sizeof n->metrics.host);
        memcpy(n->metrics.port, l.port, sizeof n->metrics.port);
        n->metrics.line = 0;
    }
    for (int k = 0; k < n->nlisten && n->metrics.port[0]; k++)
        if (!strcmp(n->listen[k].host, n->metrics.host) && !strcmp(n->listen[k].port, n->metrics.port)) {
            snprintf(err, errsize,
                     "%s: the metrics endpoint and a Modbus listener on one address; give --metrics "
                     "(or [metrics] listen) a port of its own",
                     addr_text(n->metrics.host, n->metrics.port, a, sizeof a));
            goto fail;
        }
    *c = *n;
    free(n);
    return 0;
fail:
    free(n);
    return -1;
}

int conf_rtu_same(const struct conf_rtu *a, const struct conf_rtu *b)
{
    struct conf_rtu x, y;
    memcpy(&x, a, sizeof x); /* memcpy, not assignment: the padding too */
    memcpy(&y, b, sizeof y);
    x.device_line = y.device_line = 0;
    return !memcmp(&x, &y, sizeof x);
}

int conf_link_same(const struct conf_link *a, const struct conf_link *b)
{
    struct conf_link x, y;
    memcpy(&x, a, sizeof x);
    memcpy(&y, b, sizeof y);
    x.device_line = y.device_line = 0;
    return !memcmp(&x, &y, sizeof x);
}
