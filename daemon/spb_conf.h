/* spb_conf — the [sparkplug] section of the configuration (docs/sparkplug.md,
 * "Configuration"): the broker, the Sparkplug ids and the MQTT session
 * options. conf.c hands every key of the section to spb_conf_key() and
 * calls spb_conf_check() once the file is read. No I/O but the password
 * file, read at load so a bad one is a configuration error with its line. */
#ifndef IT2ND_SPB_CONF_H
#define IT2ND_SPB_CONF_H

#include <stddef.h>

#define SPB_ID_MAX 64     /* group_id, edge_node_id, client_id (with the NUL) */
#define SPB_SECRET_MAX 256

struct spb_conf {
    int enabled;                 /* a [sparkplug] section was given          */
    int first_line;              /* its first key, for "missing key" errors  */
    char first_key[32];
    char host[256];              /* broker host (name or address, no [])     */
    int port;                    /* broker port, default 1883                */
    char group_id[SPB_ID_MAX];
    char edge_node_id[SPB_ID_MAX];
    char client_id[SPB_ID_MAX];  /* "" = it2nd-<group_id>-<edge_node_id>     */
    int keepalive;               /* s, MQTT keep alive (also the CONNACK wait) */
    int reconnect_max;           /* s, the longest wait between attempts     */
    char username[SPB_ID_MAX * 2];
    char password[SPB_SECRET_MAX]; /* the first line of password_file        */
    int password_set;
    int password_line;           /* line of password_file, 0 when not given  */
    /* TLS: tls_ca set = TLS with server verification (certificate and host
     * name); tls_cert + tls_key = a client certificate too. */
    char tls_ca[256], tls_cert[256], tls_key[256];
    int tls_ca_line, tls_cert_line, tls_key_line;
};

/* The defaults of a configuration without the section (disabled). */
void spb_conf_default(struct spb_conf *s);

/* One key of [sparkplug]. Returns 0, or -1 with the reason (without
 * file, line or key: the caller adds them) in err. line is the key's. */
int spb_conf_key(struct spb_conf *s, const char *name, const char *value, int line, char *err, size_t errsize);

/* Checks between keys once the file is read: the required keys. Returns
 * 0, or -1 with *line, key (the key to name) and err (the reason). */
int spb_conf_check(const struct spb_conf *s, int *line, char *key, size_t keysize, char *err, size_t errsize);

/* Load the TLS files as the MQTT client will (OpenSSL: the CA
 * certificates, the client certificate chain and key, and that they
 * match), so a bad one fails --check-config, start and reload with
 * "path:line: [sparkplug] key: reason". Kept out of spb_conf_key() so the
 * parser (and its fuzzer) stays free of OpenSSL. 0 or -1 with err. */
int spb_conf_check_tls(const struct spb_conf *s, const char *path, char *err, size_t errsize);

#endif
