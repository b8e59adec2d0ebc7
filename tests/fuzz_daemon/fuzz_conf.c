/* Fuzz target "conf": arbitrary text as the it2nd configuration file, read
 * by conf_load (libinih + the daemon's key parsers and cross checks).
 * Invariants (abort on violation):
 *  - success: every field of the result is inside its documented limits
 *    (counts, ranges, unique unit ids, terminated strings), as the rest of
 *    the daemon assumes without checking again; every number, word and
 *    flag key of every section holds a value its schema entry allows
 *    (daemon/conf_schema.c: the range, a word's code, or the value before
 *    any key);
 *  - failure: the struct is untouched and the message names the file and a
 *    line "PATH:N: ..." with N a line of the file; when it names a key, that
 *    key occurs on line N or above (libinih continuation lines repeat the
 *    key of an earlier line); cross-key (validation) errors name a line too;
 *  - no accepted file has a line of 199 characters or more (libinih would
 *    have split it and parsed the tail of a long comment as a setting);
 *  - no accepted file is empty or ends without a newline (what a rewrite
 *    cut short leaves); the one error without a line is that of the empty
 *    file. An input without its final newline is also run with one, so
 *    the parser behind that check is fuzzed as before;
 *  - a model id with removed = yes is never in the model list;
 *  - a line without '=' is reported with its text, quoted from that line
 *    (the message is told by its end: a section name may hold the marker;
 *    corpus/conf/noeq_* are what the fuzzer found in this harness).
 * Found by this fuzzer and fixed in daemon/conf.c: corpus/conf/long_* and
 * first_error_line.conf (message of the first error with the key of the
 * last, libinih being built with INI_STOP_ON_FIRST_ERROR 0),
 * empty_long_section.conf (an empty section's error quoted its header's
 * name cut at 63 bytes, as if that were the name).
 * Built as a libFuzzer target (make fuzzd-fuzz) and, with fuzz_main.c, as a
 * plain corpus run under make test. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "conf.h"
#include "conf_schema.h"
#include "fake_env.h"
#include "fuzz_tmp.h"
#include "it2n.h"
#include "it2n_regmap.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char path[128];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    snprintf(path, sizeof path, "%s/it2nd.conf", fuzz_tmp());
    return 0;
}

/* Where "': no '=' in this line: expected key = value" ends the message
 * (alone or with " (KEY = ...?)"), the end of the quoted text; else NULL. */
static const char *noeq_text(const char *msg)
{
    static const char mark[] = "': no '=' in this line: expected key = value";
    const char *q = NULL, *x = msg;
    while ((x = strstr(x, mark)) != NULL)
        q = x++;
    if (!q)
        return NULL;
    x = q + sizeof mark - 1;
    if (*x == 0 || (x[0] == ' ' && x[1] == '(' && strlen(x) > 8 && !strcmp(x + strlen(x) - 8, " = ...?)")))
        return q;
    return NULL;
}

static int terminated(const char *s, size_t size)
{
    return memchr(s, 0, size) != NULL;
}

/* Whether key k of the struct at base holds a value the schema allows. */
static int schema_value_ok(const void *base, const struct conf_key *k)
{
    const char *at = (const char *)base + k->off;
    long v;
    if (k->type == CONF_T_FLAG)
        return 1; /* a bit: any value is one */
    if (k->type != CONF_T_INT && k->type != CONF_T_ENUM && k->type != CONF_T_BOOL)
        return 1;
    v = k->size == 1 ? (long)*at : (long)*(const int *)(const void *)at;
    if (!k->def && v == k->unset)
        return 1;
    if (k->type == CONF_T_BOOL)
        return v == 0 || v == 1;
    for (int w = 0; k->words && k->words[w].word; w++)
        if (v == k->words[w].code)
            return 1;
    return k->type == CONF_T_INT && v >= k->lo && v <= k->hi;
}

/* Every section instance of c against the schema. */
static void check_schema(const struct conf *c)
{
    int ns;
    const struct conf_section *sec = conf_schema_sections(&ns);
    for (int i = 0; i < ns; i++) {
        const void *base[CONF_MAX_MODELS];
        int n = 1;
        switch (sec[i].id) {
        case CONF_SEC_LISTEN: n = c->nlisten; for (int k = 0; k < n; k++) base[k] = &c->listen[k]; break;
        case CONF_SEC_RTU: n = c->nrtu; for (int k = 0; k < n; k++) base[k] = &c->rtu[k]; break;
        case CONF_SEC_MODEL: n = c->nmodels; for (int k = 0; k < n; k++) base[k] = &c->model[k]; break;
        case CONF_SEC_LINK: n = c->nlinks; for (int k = 0; k < n; k++) base[k] = &c->link[k]; break;
        case CONF_SEC_SPARKPLUG: base[0] = &c->spb; break;
        case CONF_SEC_METRICS: base[0] = &c->metrics; break;
        default: base[0] = c; break;
        }
        for (int k = 0; k < n; k++)
            for (int j = 0; j < sec[i].nkeys; j++)
                if (!schema_value_ok(base[k], &sec[i].keys[j])) {
                    fuzz_note("[%s] %s out of its schema range", sec[i].name, sec[i].keys[j].name);
                    fuzz_check(0, "a key's value is one its schema allows");
                }
    }
}

static void check_ok(const struct conf *c)
{
    check_schema(c);
    fuzz_check(terminated(c->state_dir, sizeof c->state_dir) && c->state_dir[0], "state_dir");
    fuzz_check(c->snapshot_interval >= 1 && c->snapshot_interval <= 86400, "snapshot_interval range");
    fuzz_check(c->fsync == 0 || c->fsync == 1, "fsync bool");
    fuzz_check(c->max_models >= 1 && c->max_models <= CONF_MAX_MODELS, "max_models range");
    fuzz_check(c->nlisten >= 0 && c->nlisten <= CONF_MAX_LISTEN, "nlisten bound");
    for (int k = 0; k < c->nlisten; k++) {
        const struct conf_listen *l = &c->listen[k];
        fuzz_check(terminated(l->host, sizeof l->host) && terminated(l->port, sizeof l->port), "listen strings");
        long port = strtol(l->port, NULL, 10);
        fuzz_check(port >= 1 && port <= 65535, "listen port range (0 refused)");
    }
    fuzz_check(terminated(c->metrics.host, sizeof c->metrics.host) && terminated(c->metrics.port, sizeof c->metrics.port),
               "metrics strings");
    if (c->metrics.port[0]) {
        long port = strtol(c->metrics.port, NULL, 10);
        fuzz_check(port >= 1 && port <= 65535, "metrics port range (0 refused)");
        for (int k = 0; k < c->nlisten; k++)
            fuzz_check(strcmp(c->listen[k].host, c->metrics.host) || strcmp(c->listen[k].port, c->metrics.port),
                       "metrics address is not a Modbus listener's");
    }
    fuzz_check(c->max_clients >= 1 && c->max_clients <= 512, "max_clients range");
    fuzz_check(c->idle_timeout >= 1 && c->idle_timeout <= 86400, "idle_timeout range");
    fuzz_check(c->byte_timeout >= 10 && c->byte_timeout <= 60000, "byte_timeout range");
    fuzz_check(c->word_order >= 0 && c->word_order <= 3, "word order");
    fuzz_check(c->int32_word_order >= -1 && c->int32_word_order <= 3, "int32 word order");
    if (c->default_model >= 0) {  /* a model id must name a configured model */
        int found = 0;
        for (int k = 0; k < c->nmodels; k++)
            found |= c->model[k].id == c->default_model;
        fuzz_check(found, "default_model names a configured model");
    } else {
        fuzz_check(c->default_model == CONF_DEFAULT_AUTO || c->default_model == CONF_DEFAULT_NONE, "default_model");
    }
    fuzz_check(c->coord_scale >= 1 && c->coord_scale <= 10000, "coord_scale range");
    fuzz_check(c->grid_rows >= 2 && c->grid_cols >= 2 &&
                   c->grid_rows * c->grid_cols <= (int)IT2N_REGMAP_GRID_MAX_NODES, "grid size");
    fuzz_check(c->nrtu >= 0 && c->nrtu <= CONF_MAX_RTU, "nrtu bound");
    for (int k = 0; k < c->nrtu; k++) {
        const struct conf_rtu *r = &c->rtu[k];
        fuzz_check(terminated(r->name, sizeof r->name) && r->name[0], "rtu name");
        fuzz_check(terminated(r->device, sizeof r->device) && r->device[0], "rtu device");
        fuzz_check(r->baud >= 1200 && r->baud <= 4000000, "rtu baud");
        fuzz_check(r->parity == 'N' || r->parity == 'E' || r->parity == 'O', "rtu parity");
        fuzz_check(r->stop_bits == 1 || r->stop_bits == 2, "rtu stop bits");
        for (int l = 0; l < k; l++)
            fuzz_check(strcmp(c->rtu[l].name, r->name) != 0, "rtu names unique");
    }
    fuzz_check(c->nmodels >= 0 && c->nmodels <= c->max_models, "nmodels bound");
    for (int k = 0; k < c->nmodels; k++) {
        const struct conf_model *m = &c->model[k];
        fuzz_check(m->id >= 0 && m->id <= 254, "model id range");
        fuzz_check(m->unit >= 1 && m->unit <= 247, "unit id range");
        fuzz_check(m->n >= 1 && m->n <= IT2N_MAX_DEGREE && m->m >= 1 && m->m <= IT2N_MAX_DEGREE, "degrees");
        fuzz_check((m->flags & ~IT2N_F_ALL) == 0, "model flags");
        fuzz_check(!m->preload || (m->n == 3 && m->m == 3 && !(m->flags & (IT2N_F_Z | IT2N_F_TYPE1))),
                   "preload needs the paper's shape");
        for (int l = 0; l < k; l++) {
            fuzz_check(c->model[l].id != m->id, "model ids unique");
            fuzz_check(c->model[l].unit != m->unit, "unit ids unique");
        }
    }
    fuzz_check(c->nlinks >= 0 && c->nlinks <= CONF_MAX_LINKS, "nlinks bound");
    for (int k = 0; k < c->nlinks; k++) {
        const struct conf_link *l = &c->link[k];
        fuzz_check(terminated(l->name, sizeof l->name) && l->name[0], "link name");
        fuzz_check(terminated(l->device, sizeof l->device) && terminated(l->serial, sizeof l->serial),
                   "link strings");
        fuzz_check(l->type == CONF_LINK_SERIAL || l->type == CONF_LINK_USB, "link type");
        fuzz_check(l->type != CONF_LINK_SERIAL || l->device[0], "serial link has a device");
        fuzz_check(l->type != CONF_LINK_USB || l->vid || l->pid, "usb link has VID:PID");
        fuzz_check(l->baud >= 1200 && l->baud <= 4000000, "link baud");
        for (int m = 0; m < k; m++)
            fuzz_check(strcmp(c->link[m].name, l->name) != 0, "link names unique");
    }
    fuzz_check(c->link_backoff_max >= 1 && c->link_backoff_max <= 3600, "link_backoff_max range");
    fuzz_check(c->nremoved >= 0 && c->nremoved <= CONF_MAX_MODELS, "nremoved bound");
    for (int k = 0; k < c->nremoved; k++)
        for (int m = 0; m < c->nmodels; m++)
            fuzz_check(c->model[m].id != c->removed[k], "a removed model is not served");
    for (int m = 0; m < c->nmodels; m++)
        fuzz_check(!c->model[m].removed, "no model in the list is marked removed");
    if (c->spb.enabled) {
        const struct spb_conf *s = &c->spb;
        const char *ids[] = { s->group_id, s->edge_node_id, s->client_id };
        fuzz_check(terminated(s->host, sizeof s->host) && s->host[0], "sparkplug broker host");
        fuzz_check(s->port >= 1 && s->port <= 65535, "sparkplug broker port");
        for (int k = 0; k < 3; k++)
            fuzz_check(terminated(ids[k], SPB_ID_MAX) && (k == 2 || ids[k][0]) && !strpbrk(ids[k], "/+# \t"),
                       "sparkplug ids: one topic level, no wildcard");
        fuzz_check(s->keepalive >= 5 && s->keepalive <= 3600, "sparkplug keepalive range");
        fuzz_check(s->reconnect_max >= 1 && s->reconnect_max <= 3600, "sparkplug reconnect_max range");
        fuzz_check(!s->password_set || s->username[0], "sparkplug password needs a username");
    }
}

/* Start of physical line n (1-based) of data, or NULL past the end. */
static const uint8_t *line_at(const uint8_t *data, size_t size, long n, size_t *len)
{
    size_t pos = 0;
    for (long k = 1; k < n; k++) {
        const uint8_t *nl = memchr(data + pos, '\n', size - pos);
        if (!nl)
            return NULL;
        pos = (size_t)(nl - data) + 1;
    }
    if (pos >= size)
        return NULL;
    const uint8_t *nl = memchr(data + pos, '\n', size - pos);
    *len = nl ? (size_t)(nl - (data + pos)) : size - pos;
    return data + pos;
}

static int contains(const uint8_t *hay, size_t n, const char *needle)
{
    size_t k = strlen(needle);
    for (size_t p = 0; k <= n && p + k <= n; p++)
        if (memcmp(hay + p, needle, k) == 0)
            return 1;
    return 0;
}

/* Longest physical line of data. */
static size_t longest_line(const uint8_t *data, size_t size)
{
    size_t best = 0, cur = 0;
    for (size_t k = 0; k < size; k++) {
        cur = data[k] == '\n' ? 0 : cur + 1;
        if (cur > best)
            best = cur;
    }
    return best;
}

static void check_err(const uint8_t *data, size_t size, const char *err, size_t errsize)
{
    size_t plen = strlen(path);
    fuzz_check(terminated(err, errsize) && err[0], "error message present");
    fuzz_check(strncmp(err, path, plen) == 0 && err[plen] == ':', "error names the file");
    if (size == 0) {
        fuzz_check(strncmp(err + plen, ": empty file (0 bytes)", 22) == 0, "an empty file is an empty-file error");
        return;
    }
    const char *p = err + plen + 1;
    char *end;
    long line = strtol(p, &end, 10);
    if (end == p || *end != ':') {
        /* The file was written just before: "cannot open" is a failure
         * too. */
        fuzz_check(0, "error names a line");
        return;
    }
    fuzz_check(line >= 1, "error line number positive");
    size_t llen;
    fuzz_check(line_at(data, size, line, &llen) != NULL, "error line is a line of the file");
    /* "PATH:N: [section] key: reason": the key is on line N or above. */
    const char *sec = end + 1;
    if (sec[0] == ' ' && sec[1] == '[' && strstr(sec, "]: empty section: ") &&
        (!strstr(sec, "] ") || strstr(sec, "]: empty section: ") < strstr(sec, "] "))) {
        /* "PATH:N: [name]: empty section: ...": line N is that header. */
        const char *close = strstr(sec, "]: empty section: ");
        char hdr[300]; /* "[name]": a header is one line, at most 255 bytes */
        fuzz_check((size_t)(close - sec) < sizeof hdr - 2, "empty section name length");
        memcpy(hdr, sec + 1, (size_t)(close - sec));
        hdr[close - sec] = 0;
        const uint8_t *lp = line_at(data, size, line, &llen);
        fuzz_check(contains(lp, llen, hdr), "an empty section's error names its header line");
    } else if (sec[0] == ' ' && sec[1] == '[' && noeq_text(sec)) {
        /* "PATH:N: [section] 'TEXT': no '=' in this line: expected key =
         * value[ (KEY = ...?)]": TEXT (cut to 48 bytes, then "...") is
         * from line N. A section name may hold anything, the marker too:
         * the message is told by its end (noeq_text). */
        const char *q = noeq_text(sec), *t = q;
        char k[64];
        size_t n;
        while (t > sec + 2 && !(t[-3] == ']' && t[-2] == ' ' && t[-1] == '\''))
            t--;
        n = (size_t)(q - t);
        fuzz_check(n < sizeof k, "no '=' text length");
        memcpy(k, t, n);
        k[n] = 0;
        const uint8_t *lp = line_at(data, size, line, &llen);
        int found = contains(lp, llen, k);
        if (!found && n >= 3 && !memcmp(k + n - 3, "...", 3)) { /* cut after 48 bytes */
            k[n - 3] = 0;
            found = contains(lp, llen, k);
        }
        fuzz_check(found, "a line without '=' is quoted from its line");
    } else if (sec[0] == ' ' && sec[1] == '[') {
        const char *close = strstr(sec, "] ");
        fuzz_check(close != NULL, "error: [section] key form");
        const char *key = close + 2, *colon = strstr(key, ": ");
        char k[64];
        fuzz_check(colon != NULL && (size_t)(colon - key) < sizeof k, "error: key: reason form");
        memcpy(k, key, (size_t)(colon - key));
        k[colon - key] = 0;
        const uint8_t *lp = line_at(data, size, line, &llen);
        fuzz_check(k[0] && contains(data, (size_t)(lp - data) + llen, k), "error key occurs up to its line");
    }
}

static void one(const uint8_t *data, size_t size)
{
    static struct conf c, before;
    char err[512];
    fuzz_write_file(path, data, size);
    conf_default(&c);
    before = c;
    memset(err, 0, sizeof err);
    if (conf_load(&c, path, err, sizeof err) == 0) {
        check_ok(&c);
        fuzz_check(size > 0 && data[size - 1] == '\n', "an accepted file is not empty and ends with a newline");
        /* libinih (INI_MAX_LINE 200) reads a longer line as several: the
         * tail of a long comment must not be taken as a setting. */
        fuzz_check(longest_line(data, size) < 199, "no over-long line accepted");
    } else {
        fuzz_note("conf_load error: %s", err);
        fuzz_check(memcmp(&c, &before, sizeof c) == 0, "failed load leaves the config untouched");
        check_err(data, size, err, sizeof err);
        if (size == 0 || data[size - 1] != '\n')
            fuzz_check(strstr(err, size ? ": no newline at the end of the last line: " : ": empty file") != NULL,
                       "a file cut short is refused as such");
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static uint8_t buf[64 * 1024 + 1];
    if (size > 64 * 1024)
        return 0;
    one(data, size);
    if (size && data[size - 1] != '\n') {
        memcpy(buf, data, size);
        buf[size] = '\n';
        one(buf, size + 1);
    }
    return 0;
}
