/* spb_payload.c — see spb_payload.h. protobuf-c does the wire format; this
 * file only lays out the message structs. */
#include "spb_payload.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "spb.pb-c.h"

#define SPB_PROPS 3

/* One metric with everything it points to, so a builder is one array. */
struct slot {
    Spb__Payload__Metric m;
    Spb__Payload__PropertySet ps;
    Spb__Payload__PropertyValue pv[SPB_PROPS];
    Spb__Payload__PropertyValue *pvp[SPB_PROPS];
    char *keys[SPB_PROPS];
    char *strs[2 * SPB_PROPS + 2]; /* owned copies: name, string value, props */
    int nstrs;
    uint8_t *bytes; /* owned copy of an array value */
};

struct spb_payload {
    struct slot *s;
    Spb__Payload__Metric **mp;
    size_t n, cap;
};

int spb_payload_val_equal(int type, const struct spb_payload_val *a, const struct spb_payload_val *b)
{
    if (a->null || b->null)
        return a->null == b->null;
    if (type == SPB_PAYLOAD_FLOAT)
        return !memcmp(&a->f, &b->f, sizeof a->f);
    if (type == SPB_PAYLOAD_STRING)
        return a->s && b->s ? !strcmp(a->s, b->s) : a->s == b->s;
    return a->u == b->u;
}

struct spb_payload *spb_payload_new(size_t cap)
{
    struct spb_payload *pl = calloc(1, sizeof *pl);
    if (!pl)
        return NULL;
    pl->s = calloc(cap ? cap : 1, sizeof *pl->s);
    pl->mp = calloc(cap ? cap : 1, sizeof *pl->mp);
    if (!pl->s || !pl->mp) {
        spb_payload_free(pl);
        return NULL;
    }
    pl->cap = cap;
    return pl;
}

void spb_payload_free(struct spb_payload *pl)
{
    if (!pl)
        return;
    for (size_t k = 0; k < pl->n; k++) {
        for (int j = 0; j < pl->s[k].nstrs; j++)
            free(pl->s[k].strs[j]);
        free(pl->s[k].bytes);
    }
    free(pl->s);
    free(pl->mp);
    free(pl);
}

static char *own(struct slot *s, const char *str)
{
    char *c;
    if (s->nstrs == (int)(sizeof s->strs / sizeof s->strs[0]) || !(c = strdup(str)))
        return NULL;
    s->strs[s->nstrs++] = c;
    return c;
}

int spb_payload_add(struct spb_payload *pl, const char *name, uint64_t alias, int type, uint64_t ts,
                    const struct spb_payload_val *v)
{
    static const Spb__Payload__Metric init = SPB__PAYLOAD__METRIC__INIT;
    struct slot *s;
    Spb__Payload__Metric *m;
    if (pl->n == pl->cap)
        return -1;
    s = &pl->s[pl->n];
    memset(s, 0, sizeof *s);
    m = &s->m;
    *m = init;
    if (name) {
        if (!(m->name = own(s, name)))
            return -1;
        m->has_datatype = 1;
        m->datatype = (uint32_t)type;
    }
    if (alias) {
        m->has_alias = 1;
        m->alias = alias;
    }
    m->has_timestamp = 1;
    m->timestamp = ts;
    if (v->null) {
        m->has_is_null = 1;
        m->is_null = 1;
    } else {
        switch (type) {
        case SPB_PAYLOAD_INT16:
        case SPB_PAYLOAD_INT32:
        case SPB_PAYLOAD_UINT16:
        case SPB_PAYLOAD_UINT32:
            m->value_case = SPB__PAYLOAD__METRIC__VALUE_INT_VALUE;
            m->int_value = (uint32_t)v->u;
            break;
        case SPB_PAYLOAD_INT64:
        case SPB_PAYLOAD_UINT64:
            m->value_case = SPB__PAYLOAD__METRIC__VALUE_LONG_VALUE;
            m->long_value = v->u;
            break;
        case SPB_PAYLOAD_FLOAT:
            m->value_case = SPB__PAYLOAD__METRIC__VALUE_FLOAT_VALUE;
            m->float_value = v->f;
            break;
        case SPB_PAYLOAD_BOOLEAN:
            m->value_case = SPB__PAYLOAD__METRIC__VALUE_BOOLEAN_VALUE;
            m->boolean_value = v->u != 0;
            break;
        case SPB_PAYLOAD_STRING:
            m->value_case = SPB__PAYLOAD__METRIC__VALUE_STRING_VALUE;
            if (!(m->string_value = own(s, v->s ? v->s : "")))
                return -1;
            break;
        case SPB_PAYLOAD_FLOATARRAY:
            m->value_case = SPB__PAYLOAD__METRIC__VALUE_BYTES_VALUE;
            if (v->nb) {
                if (!v->b || !(s->bytes = malloc(v->nb)))
                    return -1;
                memcpy(s->bytes, v->b, v->nb);
            }
            m->bytes_value.data = s->bytes;
            m->bytes_value.len = v->nb;
            break;
        default: return -1;
        }
    }
    pl->mp[pl->n] = m;
    return (int)pl->n++;
}

int spb_payload_prop(struct spb_payload *pl, int idx, const char *key, const char *value)
{
    static const Spb__Payload__PropertySet ps_init = SPB__PAYLOAD__PROPERTY_SET__INIT;
    static const Spb__Payload__PropertyValue pv_init = SPB__PAYLOAD__PROPERTY_VALUE__INIT;
    struct slot *s;
    size_t k;
    if (idx < 0 || (size_t)idx >= pl->n)
        return -1;
    s = &pl->s[idx];
    if (!s->m.properties) {
        s->ps = ps_init;
        s->ps.keys = s->keys;
        s->ps.values = s->pvp;
        s->m.properties = &s->ps;
    }
    k = s->ps.n_keys;
    if (k == SPB_PROPS)
        return -1;
    s->pv[k] = pv_init;
    s->pv[k].has_type = 1;
    s->pv[k].type = SPB_PAYLOAD_STRING;
    s->pv[k].value_case = SPB__PAYLOAD__PROPERTY_VALUE__VALUE_STRING_VALUE;
    if (!(s->pv[k].string_value = own(s, value)) || !(s->keys[k] = own(s, key)))
        return -1;
    s->pvp[k] = &s->pv[k];
    s->ps.n_keys = s->ps.n_values = k + 1;
    return 0;
}

void spb_payload_historical(struct spb_payload *pl)
{
    for (size_t k = 0; k < pl->n; k++) {
        pl->s[k].m.has_is_historical = 1;
        pl->s[k].m.is_historical = 1;
    }
}

int spb_payload_pack(struct spb_payload *pl, uint64_t ts, int seq, uint8_t **out, size_t *len)
{
    Spb__Payload p = SPB__PAYLOAD__INIT;
    size_t n;
    p.has_timestamp = 1;
    p.timestamp = ts;
    p.n_metrics = pl->n;
    p.metrics = pl->mp;
    if (seq >= 0) {
        p.has_seq = 1;
        p.seq = (uint64_t)seq;
    }
    n = spb__payload__get_packed_size(&p);
    if (!(*out = malloc(n ? n : 1)))
        return -1;
    *len = spb__payload__pack(&p, *out);
    return 0;
}

int spb_payload_cmd_parse(const uint8_t *buf, size_t len, uint64_t rebirth_alias, struct spb_payload_cmd *cmd,
                          char *why, size_t whysize)
{
    Spb__Payload *p = spb__payload__unpack(NULL, len, buf);
    int rc = 0;
    memset(cmd, 0, sizeof *cmd);
    if (!p) {
        snprintf(why, whysize, "not a Sparkplug B payload (protobuf decoding failed, %zu bytes)", len);
        return -1;
    }
    cmd->nmetrics = p->n_metrics > 1000000 ? 1000000 : (int)p->n_metrics;
    for (size_t k = 0; k < p->n_metrics; k++) {
        const Spb__Payload__Metric *m = p->metrics[k];
        int is_rebirth = (m->name && !strcmp(m->name, "Node Control/Rebirth")) ||
                         (!m->name && m->has_alias && rebirth_alias && m->alias == rebirth_alias);
        if (!is_rebirth)
            continue;
        if (m->value_case != SPB__PAYLOAD__METRIC__VALUE_BOOLEAN_VALUE ||
            (m->has_datatype && m->datatype != SPB_PAYLOAD_BOOLEAN)) {
            snprintf(why, whysize, "Node Control/Rebirth must be a Boolean");
            rc = -1;
            break;
        }
        if (m->boolean_value)
            cmd->rebirth = 1;
    }
    spb__payload__free_unpacked(p, NULL);
    return rc;
}

int spb_payload_cmd_each(const uint8_t *buf, size_t len, void (*fn)(void *ctx, const struct spb_payload_in *m),
                         void *ctx, char *why, size_t whysize)
{
    Spb__Payload *p = spb__payload__unpack(NULL, len, buf);
    if (!p) {
        snprintf(why, whysize, "not a Sparkplug B payload (protobuf decoding failed, %zu bytes)", len);
        return -1;
    }
    for (size_t k = 0; k < p->n_metrics; k++) {
        const Spb__Payload__Metric *m = p->metrics[k];
        struct spb_payload_in in;
        memset(&in, 0, sizeof in);
        in.name = m->name;
        in.has_alias = m->has_alias;
        in.alias = m->alias;
        in.has_datatype = m->has_datatype;
        in.datatype = m->datatype;
        switch (m->value_case) {
        case SPB__PAYLOAD__METRIC__VALUE_INT_VALUE:
            in.kind = SPB_PAYLOAD_IN_INT;
            in.u = m->int_value;
            break;
        case SPB__PAYLOAD__METRIC__VALUE_LONG_VALUE:
            in.kind = SPB_PAYLOAD_IN_LONG;
            in.u = m->long_value;
            break;
        case SPB__PAYLOAD__METRIC__VALUE_FLOAT_VALUE:
            in.kind = SPB_PAYLOAD_IN_FLOAT;
            in.d = m->float_value;
            break;
        case SPB__PAYLOAD__METRIC__VALUE_DOUBLE_VALUE:
            in.kind = SPB_PAYLOAD_IN_FLOAT;
            in.d = m->double_value;
            break;
        case SPB__PAYLOAD__METRIC__VALUE_BOOLEAN_VALUE:
            in.kind = SPB_PAYLOAD_IN_BOOL;
            in.u = m->boolean_value != 0;
            break;
        case SPB__PAYLOAD__METRIC__VALUE__NOT_SET: in.kind = SPB_PAYLOAD_IN_NONE; break;
        default: in.kind = SPB_PAYLOAD_IN_OTHER; break;
        }
        fn(ctx, &in);
    }
    spb__payload__free_unpacked(p, NULL);
    return 0;
}

/* ---- STATE (JSON) ---- */

struct js {
    const uint8_t *p, *end;
};

static void js_ws(struct js *j)
{
    while (j->p < j->end && (*j->p == ' ' || *j->p == '\t' || *j->p == '\n' || *j->p == '\r'))
        j->p++;
}

static int js_lit(struct js *j, const char *lit)
{
    size_t n = strlen(lit);
    if ((size_t)(j->end - j->p) < n || memcmp(j->p, lit, n))
        return 0;
    j->p += n;
    return 1;
}

/* A JSON string; its bytes (escapes kept as written) into out when it
 * fits, else an empty key (matches nothing). */
static int js_str(struct js *j, char *out, size_t size)
{
    size_t n = 0;
    if (j->p >= j->end || *j->p != '"')
        return -1;
    j->p++;
    while (j->p < j->end && *j->p != '"') {
        if (*j->p < 0x20)
            return -1;
        if (*j->p == '\\') {
            if (++j->p >= j->end)
                return -1;
        }
        if (n + 1 < size)
            out[n] = (char)*j->p;
        n++;
        j->p++;
    }
    if (j->p >= j->end)
        return -1;
    j->p++;
    out[n + 1 < size ? n : 0] = 0;
    return 0;
}

/* Any other value: skipped (a string; an object or array by bracket
 * depth, strings inside honoured; a number or literal up to the next
 * separator), bounded by len. */
static int js_skip(struct js *j)
{
    char tmp[2];
    int depth = 0;
    if (j->p < j->end && *j->p == '"')
        return js_str(j, tmp, sizeof tmp);
    if (j->p < j->end && (*j->p == '{' || *j->p == '[')) {
        do {
            if (j->p >= j->end)
                return -1;
            if (*j->p == '"') {
                if (js_str(j, tmp, sizeof tmp))
                    return -1;
                continue;
            }
            if (*j->p == '{' || *j->p == '[')
                depth++;
            else if (*j->p == '}' || *j->p == ']')
                depth--;
            j->p++;
        } while (depth > 0);
        return 0;
    }
    if (j->p >= j->end || *j->p == ',' || *j->p == '}')
        return -1;
    while (j->p < j->end && *j->p != ',' && *j->p != '}' && *j->p != ' ' && *j->p != '\t' && *j->p != '\n' &&
           *j->p != '\r')
        j->p++;
    return 0;
}

int spb_payload_state_parse(const uint8_t *buf, size_t len, int *online, uint64_t *ts, char *why, size_t whysize)
{
    struct js j = {buf, buf + len};
    int have_on = 0, have_ts = 0;
    char key[16];
    js_ws(&j);
    if (!js_lit(&j, "{")) {
        snprintf(why, whysize, "not a JSON object (Sparkplug 3.0 STATE is {\"online\": ..., \"timestamp\": ...})");
        return -1;
    }
    js_ws(&j);
    if (js_lit(&j, "}"))
        goto done;
    for (;;) {
        js_ws(&j);
        if (js_str(&j, key, sizeof key))
            goto bad;
        js_ws(&j);
        if (!js_lit(&j, ":"))
            goto bad;
        js_ws(&j);
        if (!strcmp(key, "online")) {
            if (js_lit(&j, "true"))
                *online = 1;
            else if (js_lit(&j, "false"))
                *online = 0;
            else {
                snprintf(why, whysize, "\"online\" must be true or false");
                return -1;
            }
            have_on = 1;
        } else if (!strcmp(key, "timestamp")) {
            uint64_t v = 0;
            int digits = 0;
            while (j.p < j.end && *j.p >= '0' && *j.p <= '9') {
                if (v > (UINT64_MAX - 9) / 10) {
                    snprintf(why, whysize, "\"timestamp\" out of range");
                    return -1;
                }
                v = v * 10 + (uint64_t)(*j.p++ - '0');
                digits++;
            }
            if (!digits || (j.p < j.end && (*j.p == '.' || *j.p == 'e' || *j.p == 'E' || *j.p == '-'))) {
                snprintf(why, whysize, "\"timestamp\" must be ms since the epoch (an unsigned integer)");
                return -1;
            }
            *ts = v;
            have_ts = 1;
        } else if (js_skip(&j)) {
            goto bad;
        }
        js_ws(&j);
        if (js_lit(&j, ","))
            continue;
        if (js_lit(&j, "}"))
            break;
        goto bad;
    }
done:
    js_ws(&j);
    if (j.p != j.end)
        goto bad;
    if (!have_on || !have_ts) {
        snprintf(why, whysize, "missing \"%s\"", have_on ? "timestamp" : "online");
        return -1;
    }
    return 0;
bad:
    snprintf(why, whysize, "malformed JSON at byte %zu", (size_t)(j.p - buf));
    return -1;
}
