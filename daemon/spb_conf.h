/* spb_conf — the [sparkplug] section of the configuration (docs/sparkplug.md,
 * "Configuration"): the broker, the Sparkplug ids and the MQTT session
 * options. conf.c parses the section's keys through the schema
 * (conf_schema.c) with the parsers below and calls spb_conf_check() once
 * the file is read. No I/O but the password
 * file, read at load so a bad one is a configuration error with its line. */
#ifndef IT2ND_SPB_CONF_H
#define IT2ND_SPB_CONF_H

#include <stddef.h>

#define SPB_ID_MAX 64 /* group_id, edge_node_id, client_id (with the NUL) */
#define SPB_SECRET_MAX 256

struct spb_conf {
    int enabled;    /* a [sparkplug] section was given          */
    int first_line; /* its first key, for "missing key" errors  */
    char first_key[32];
    char host[256]; /* broker host (name or address, no [])     */
    int port;       /* broker port, default 1883                */
    char group_id[SPB_ID_MAX];
    char edge_node_id[SPB_ID_MAX];
    char client_id[SPB_ID_MAX]; /* "" = it2nd-<group_id>-<edge_node_id>     */
    int keepalive;              /* s, MQTT keep alive (also the CONNACK wait) */
    int reconnect_max;          /* s, the longest wait between attempts     */
    char username[SPB_ID_MAX * 2];
    char password[SPB_SECRET_MAX]; /* the first line of password_file        */
    int password_set;
    int password_line; /* line of password_file, 0 when not given  */
    /* TLS: tls_ca set = TLS with server verification (certificate and host
     * name); tls_cert + tls_key = a client certificate too. */
    char tls_ca[256], tls_cert[256], tls_key[256];
    int tls_ca_line, tls_cert_line, tls_key_line;
    /* primary_host_id set: births wait for its STATE online (Sparkplug
     * 3.0); changes made while it or the broker is away are stored, at
     * most store_forward (0: not stored; -1: not given, the default). */
    char primary_host_id[SPB_ID_MAX];
    int store_forward;
};

/* store_forward_max when primary_host_id is set and the key is not given. */
#define SPB_SF_DEFAULT 10000
#define SPB_SF_LIMIT 1000000

/* The defaults of a configuration without the section (disabled). */
void spb_conf_default(struct spb_conf *s);

/* The value parsers of [sparkplug]'s own types (its keys, types and
 * ranges are in daemon/conf_schema.c, which conf.c parses through). */
/* A Sparkplug id (group_id, edge_node_id, ...): one MQTT topic level,
 * 1..SPB_ID_MAX-1 printable ASCII bytes. 1 if v is one. */
int spb_conf_valid_id(const char *v);
/* broker: "host:port", "[v6]:port" or "host" (port 1883) into s->host,
 * s->port. 0, or -1 (s->host, s->port may be written). */
int spb_conf_parse_broker(struct spb_conf *s, const char *v);
/* password_file: the first line of path into s->password. 0, or -1 with
 * the reason in err. */
int spb_conf_read_password(struct spb_conf *s, const char *path, char *err, size_t errsize);

/* Whether two [sparkplug] sections say the same, wherever their keys
 * stand in the file (the lines and the first key's name are where, not
 * what): a reload logs a change only when there is one. 1 or 0. */
int spb_conf_same(const struct spb_conf *a, const struct spb_conf *b);

/* The store-and-forward bound in effect (0: off). */
int spb_conf_sf_max(const struct spb_conf *s);

/* Checks between keys once the file is read: the required keys. Returns
 * 0, or -1 with *line, key (the key to name) and err (the reason). */
int spb_conf_check(const struct spb_conf *s, int *line, char *key, size_t keysize, char *err, size_t errsize);

/* Load the TLS files as the MQTT client will (OpenSSL: the CA
 * certificates, the client certificate chain and key, and that they
 * match), so a bad one fails --check-config, start and reload with
 * "path:line: [sparkplug] key: reason". Kept out of the key parsers so the
 * parser (and its fuzzer) stays free of OpenSSL. 0 or -1 with err. */
int spb_tls_check(const struct spb_conf *s, const char *path, char *err, size_t errsize);

#endif
