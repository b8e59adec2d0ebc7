/* conf_schema — the one table of it2nd's configuration: every section
 * kind and every key with its type, range or values, default, reload
 * behaviour and help. conf.c parses through it (no key is named anywhere
 * else in the parser), --check-config reports with it ("expected ...",
 * "did you mean"), it2nd --config-keys prints it, docs/daemon.md's key
 * tables and the config fuzzer's dictionary are generated from it
 * (tests/docs/docfig.py, tests/fuzz_daemon/fuzz_daemon.mk). Pure data and
 * lookups: no I/O but conf_schema_print(). */
#ifndef IT2ND_CONF_SCHEMA_H
#define IT2ND_CONF_SCHEMA_H

#include <stddef.h>
#include <stdio.h>

/* How a value is read (conf.c stores it; the compound types have a parser
 * of their own there or in spb_conf.c/acl.c). */
enum conf_type {
    CONF_T_INT,      /* lo..hi, base 10; words[] may add named values    */
    CONF_T_ENUM,     /* one of words[] (case ignored)                    */
    CONF_T_BOOL,     /* yes/no, true/false, on/off, 1/0                  */
    CONF_T_FLAG,     /* a bool kept as bit `bit` of an unsigned          */
    CONF_T_STR,      /* 1..size-1 bytes                                  */
    CONF_T_PATH,     /* a path, 1..size-1 bytes                          */
    CONF_T_FILE,     /* a path readable at load                          */
    CONF_T_SECRET,   /* a file whose first line is the secret            */
    CONF_T_USER,     /* a user name known to the system at load          */
    CONF_T_LISTEN,   /* host:port appended to the listeners, or none     */
    CONF_T_ADDR,     /* host:port of this section's listener             */
    CONF_T_ENDPOINT, /* host:port of the metrics endpoint, or none       */
    CONF_T_ALLOW,    /* IPv4/IPv6 addresses and prefixes (acl.c)         */
    CONF_T_USB,      /* VID:PID[:serial] in hex                          */
    CONF_T_BROKER,   /* host[:port] of an MQTT broker (spb_conf.c)       */
    CONF_T_SPB_ID    /* one MQTT topic level (spb_conf.c)                */
};

/* A named value of an ENUM (or a word an INT also takes). hidden: an
 * alias taken but not listed ("N" for none). */
struct conf_word {
    const char *word;
    int code;
    int hidden;
};

/* Key flags. */
#define CONF_K_RESTART 1u    /* a reload logs a change and keeps the running value */
#define CONF_K_REPEAT 2u     /* may be given more than once (values add up)      */
#define CONF_K_REQUIRED 4u   /* the section is refused without it                */
#define CONF_K_RS485 8u      /* needs rs485 = yes in its section                 */
#define CONF_K_KERNEL 16u    /* RS-485 switched by the kernel (rs485_rts = none) */
#define CONF_K_LIBMODBUS 32u /* RS-485 switched by libmodbus (rs485_rts = up/down) */

struct conf_key {
    const char *name;
    enum conf_type type;
    long lo, hi;                   /* INT: the range                         */
    const struct conf_word *words; /* ENUM values, INT named values; {NULL} ends */
    const char *unit;              /* "seconds": "expected seconds 1..60"    */
    const char *note;              /* "0: off": "expected ... (0: off)"      */
    size_t off, size;              /* the value in its section's struct      */
    unsigned bit;                  /* FLAG: its bit                          */
    unsigned set;                  /* bit of the section's `set` mask, or 0  */
    size_t line_off;               /* the key's line in the struct, plus 1; 0: none */
    const char *def;               /* the default, as the file would write it; NULL: none */
    const char *def_doc;           /* the default as the docs say it (def NULL or explained) */
    int unset;                     /* INT/ENUM/BOOL without def: the value before any key */
    unsigned flags;                /* CONF_K_*                               */
    const char *help;              /* one line (markdown) for the reference  */
};

/* Section kinds (conf.c finds the struct a section's keys go to by it). */
enum conf_sec {
    CONF_SEC_DAEMON,
    CONF_SEC_MODBUS,
    CONF_SEC_LISTEN,
    CONF_SEC_RTU,
    CONF_SEC_MODEL,
    CONF_SEC_LINK,
    CONF_SEC_SPARKPLUG,
    CONF_SEC_METRICS
};

struct conf_section {
    const char *name; /* "daemon"; "rtu:" for [rtu:NAME]            */
    enum conf_sec id;
    const char *arg;   /* "NAME", "ID" after the colon; NULL: none   */
    const char *title; /* the docs' heading after the section's name */
    const char *needs; /* why an empty section of this kind is refused */
    size_t set_off;    /* the `unsigned set` mask, plus 1; 0: none   */
    const struct conf_key *keys;
    int nkeys;
};

#define CONF_SCHEMA_MAX_KEYS 16 /* keys of the largest section (checked by test_conf) */

/* The table: *n sections. */
const struct conf_section *conf_schema_sections(int *n);

/* The kind of a section as written in a header ("rtu:a" -> [rtu:NAME]),
 * NULL for an unknown one (a named kind needs its name after the colon). */
const struct conf_section *conf_schema_section(const char *header);

/* Key `name` of section s (exact), or NULL; its index in s->keys in *idx
 * when idx is not NULL. */
const struct conf_key *conf_schema_key(const struct conf_section *s, const char *name, int *idx);

/* "Did you mean": the key of s nearest to a misspelt name (edit distance,
 * case ignored), or a key of that exact name in another section (then
 * *where is that section; else NULL); NULL when none is close. */
const char *conf_schema_suggest_key(const struct conf_section *s, const char *name, const struct conf_section **where);

/* The section kind nearest to an unknown header's kind, or NULL. */
const struct conf_section *conf_schema_suggest_section(const char *header);

/* The listed word of k nearest to a value k refused, or NULL. */
const char *conf_schema_suggest_word(const struct conf_key *k, const char *value);

/* A whole decimal number in [lo, hi] (nothing before or after it) into
 * *out: the one number reader of every config value (keys and the port of
 * an address). 0, or -1. */
int conf_schema_int(const char *v, int lo, int hi, int *out);

/* Read an INT, ENUM, BOOL or FLAG value of k into *out. 0, or -1. */
int conf_schema_number(const struct conf_key *k, const char *value, long *out);

/* What k accepts, for errors: "expected seconds 1..86400", "expected yes
 * or no", "expected auto or microseconds 500..1000000". */
void conf_schema_expect(const struct conf_key *k, char *buf, size_t size);

/* The reference: format "text" (it2nd --config-keys), "markdown" (the
 * tables of docs/daemon.md, one "### `[section]`" heading each) or "dict"
 * (a libFuzzer dictionary: section and key names, words). 0, or -1 for an
 * unknown format. */
int conf_schema_print(FILE *f, const char *format);

#endif
