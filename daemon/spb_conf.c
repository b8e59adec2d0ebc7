/* spb_conf.c — see spb_conf.h. */
#include "spb_conf.h"
#include "conf_schema.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ERR(...)                             \
    do {                                     \
        snprintf(err, errsize, __VA_ARGS__); \
        return -1;                           \
    } while (0)

void spb_conf_default(struct spb_conf *s)
{
    memset(s, 0, sizeof *s);
    s->port = 1883;
    s->keepalive = 30;
    s->reconnect_max = 30;
    s->store_forward = -1;
}

int spb_conf_same(const struct spb_conf *a, const struct spb_conf *b)
{
    struct spb_conf x, y;
    struct spb_conf *v[2] = {&x, &y};
    memcpy(&x, a, sizeof x); /* memcpy, not assignment: the padding too */
    memcpy(&y, b, sizeof y);
    for (int k = 0; k < 2; k++) {
        v[k]->first_line = v[k]->password_line = 0;
        v[k]->tls_ca_line = v[k]->tls_cert_line = v[k]->tls_key_line = 0;
        memset(v[k]->first_key, 0, sizeof v[k]->first_key);
    }
    return !memcmp(&x, &y, sizeof x);
}

int spb_conf_sf_max(const struct spb_conf *s)
{
    if (s->store_forward >= 0)
        return s->store_forward;
    return s->primary_host_id[0] ? SPB_SF_DEFAULT : 0;
}

/* A Sparkplug id is one MQTT topic level: no '/', '+', '#' (the topic
 * separators and wildcards, spec 4.1.1), and printable ASCII here so it
 * reads the same in logs, topics and the docs. */
int spb_conf_valid_id(const char *v)
{
    if (!*v || strlen(v) >= SPB_ID_MAX)
        return 0;
    for (const char *c = v; *c; c++)
        if (*c < 0x21 || *c > 0x7e || *c == '/' || *c == '+' || *c == '#')
            return 0;
    return 1;
}

int spb_conf_parse_broker(struct spb_conf *s, const char *v)
{
    const char *colon = NULL;
    size_t hlen;
    if (v[0] == '[') {
        const char *close = strchr(v, ']');
        if (!close || (close[1] && close[1] != ':'))
            return -1;
        hlen = (size_t)(close - v - 1);
        v++;
        colon = close[1] ? close + 1 : NULL;
    } else {
        colon = strrchr(v, ':');
        if (colon && strchr(v, ':') != colon)
            return -1; /* a bare IPv6 address needs [] */
        hlen = colon ? (size_t)(colon - v) : strlen(v);
    }
    if (hlen == 0 || hlen >= sizeof s->host)
        return -1;
    memcpy(s->host, v, hlen);
    s->host[hlen] = 0;
    if (!colon)
        s->port = 1883; /* the MQTT port (IANA) */
    else if (conf_schema_int(colon + 1, 1, 65535, &s->port))
        return -1;
    return 0;
}

int spb_conf_read_password(struct spb_conf *s, const char *path, char *err, size_t errsize)
{
    FILE *f = fopen(path, "r");
    char *line = NULL;
    size_t cap = 0;
    ssize_t n;
    if (!f)
        ERR("cannot open '%s': %s", path, strerror(errno));
    n = getline(&line, &cap, f);
    fclose(f);
    if (n < 0) {
        free(line);
        ERR("'%s' is empty: its first line is the password", path);
    }
    while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r'))
        line[--n] = 0;
    if (n == 0 || (size_t)n >= sizeof s->password) {
        free(line);
        ERR("the first line of '%s' must hold the password (1..%zu bytes)", path, sizeof s->password - 1);
    }
    memcpy(s->password, line, (size_t)n + 1);
    memset(line, 0, cap);
    free(line);
    s->password_set = 1;
    return 0;
}

int spb_conf_check(const struct spb_conf *s, int *line, char *key, size_t keysize, char *err, size_t errsize)
{
    static const char *const need[] = {"broker", "group_id", "edge_node_id"};
    const char *have[] = {s->host, s->group_id, s->edge_node_id};
    if (!s->enabled)
        return 0;
    for (size_t k = 0; k < sizeof need / sizeof need[0]; k++)
        if (!have[k][0]) {
            *line = s->first_line;
            snprintf(key, keysize, "%s", s->first_key);
            ERR("%s is required in this section", need[k]);
        }
    if (!!s->tls_cert[0] != !!s->tls_key[0]) {
        *line = s->tls_cert[0] ? s->tls_cert_line : s->tls_key_line;
        snprintf(key, keysize, "%s", s->tls_cert[0] ? "tls_cert" : "tls_key");
        ERR("needs %s in this section (a client certificate and its key go together)",
            s->tls_cert[0] ? "tls_key" : "tls_cert");
    }
    if (s->tls_cert[0] && !s->tls_ca[0]) {
        *line = s->tls_cert_line;
        snprintf(key, keysize, "tls_cert");
        ERR("needs tls_ca in this section (TLS verifies the broker's certificate)");
    }
    if (s->password_set && !s->username[0]) {
        *line = s->password_line;
        snprintf(key, keysize, "password_file");
        ERR("needs username in this section");
    }
    return 0;
}
