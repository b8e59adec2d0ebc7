/* spb_tls.c — spb_tls_check (spb_conf.h): the TLS files of
 * [sparkplug] loaded with OpenSSL, the library libmosquitto uses. */
#include "spb_conf.h"

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <stdio.h>

/* Encrypted keys are not supported: never prompt on a terminal. */
static int no_password(char *buf, int size, int rwflag, void *u)
{
    (void)buf;
    (void)size;
    (void)rwflag;
    (void)u;
    return 0;
}

static const char *ssl_reason(void)
{
    static char buf[160];
    unsigned long e = ERR_peek_last_error();
    ERR_error_string_n(e, buf, sizeof buf);
    ERR_clear_error();
    return e ? buf : "unknown error";
}

int spb_tls_check(const struct spb_conf *s, const char *path, char *err, size_t errsize)
{
    SSL_CTX *ctx;
    int rc = -1;
    if (!s->enabled || !s->tls_ca[0])
        return 0;
    if (!path)
        path = "built-in";
    ctx = SSL_CTX_new(TLS_client_method());
    if (!ctx) {
        snprintf(err, errsize, "%s: [sparkplug]: cannot create a TLS context: %s", path, ssl_reason());
        return -1;
    }
    SSL_CTX_set_default_passwd_cb(ctx, no_password);
    if (SSL_CTX_load_verify_locations(ctx, s->tls_ca, NULL) != 1)
        snprintf(err, errsize, "%s:%d: [sparkplug] tls_ca: cannot load CA certificates from '%s': %s", path,
                 s->tls_ca_line, s->tls_ca, ssl_reason());
    else if (s->tls_cert[0] && SSL_CTX_use_certificate_chain_file(ctx, s->tls_cert) != 1)
        snprintf(err, errsize, "%s:%d: [sparkplug] tls_cert: cannot load a certificate from '%s': %s", path,
                 s->tls_cert_line, s->tls_cert, ssl_reason());
    else if (s->tls_key[0] && SSL_CTX_use_PrivateKey_file(ctx, s->tls_key, SSL_FILETYPE_PEM) != 1 &&
             ERR_GET_REASON(ERR_peek_last_error()) != X509_R_KEY_VALUES_MISMATCH)
        snprintf(err, errsize,
                 "%s:%d: [sparkplug] tls_key: cannot load a private key (PEM, not encrypted) from '%s': %s", path,
                 s->tls_key_line, s->tls_key, ssl_reason());
    else if (s->tls_key[0] && SSL_CTX_check_private_key(ctx) != 1) {
        ERR_clear_error();
        snprintf(err, errsize, "%s:%d: [sparkplug] tls_key: '%s' is not the key of tls_cert '%s' (line %d)", path,
                 s->tls_key_line, s->tls_key, s->tls_cert, s->tls_cert_line);
    } else
        rc = 0;
    SSL_CTX_free(ctx);
    return rc;
}
