/* conf — it2nd configuration: built-in defaults, INI file (libinih), and
 * validation. Every section and key, its type, range, default and help,
 * is in the schema (conf_schema.h); conf.c reads every key through it.
 * docs/daemon.md's key tables are generated from it; the commented example
 * is daemon/it2nd.conf.example. */
#ifndef IT2ND_CONF_H
#define IT2ND_CONF_H

#include <stddef.h>
#include <stdint.h>

#define CONF_MAX_LISTEN 8
#define CONF_MAX_RTU 8
#define CONF_MAX_MODELS 32
#define CONF_MAX_LINKS 16
#define CONF_NAME 32
#define CONF_PATH 256
#define CONF_MAX_ALLOW 32

#include "acl.h"
#include "spb_conf.h"

struct conf_listen {
    char name[CONF_NAME]; /* [listen:NAME]; "" for a tcp_listen line */
    char host[64];
    char port[8];
    int line;      /* config line of the address, 0 built-in */
    int read_only; /* 1: no Modbus write may change a model */
    int nallow;    /* 0: every client address */
    struct acl_prefix allow[CONF_MAX_ALLOW];
};

struct conf_rtu {
    char name[CONF_NAME];
    char device[CONF_PATH];
    int baud;
    char parity;   /* 'N', 'E', 'O' */
    int stop_bits; /* 1 or 2 */
    int t35_us;    /* inter-frame silence, 0 = the spec's t3.5 for the baud rate */
    int read_only; /* 1: no Modbus write may change a model through this port */
    int rs485;     /* 1: RS-485 (see rts for who switches the line) */
    /* RS-485 options, only with rs485 = 1; -1 = leave as the driver or
     * libmodbus has it. Two exclusive ways to switch the transceiver:
     * rts = CONF_RTS_NONE: the kernel driver does (TIOCSRS485), tuned by
     * the rs485_* kernel fields; UP/DOWN: libmodbus raises/lowers RTS
     * around each reply (modbus_rtu_set_rts), rts_delay_us around it. */
    int rts;             /* enum conf_rts */
    int rts_delay_us;    /* -1 or 0..CONF_RTS_DELAY_US_MAX */
    int rts_on_send;     /* kernel: -1, 0 (RTS low while sending), 1 (high) */
    int delay_before_ms; /* kernel: -1 or 0..CONF_RS485_DELAY_MS_MAX */
    int delay_after_ms;  /* kernel: -1 or 0..CONF_RS485_DELAY_MS_MAX */
    int termination;     /* kernel: -1, 0, 1 (SER_RS485_TERMINATE_BUS) */
    int strict;          /* 1: a device refusing any of it is not served */
    int device_line;     /* config line of device, for conflicts */
};

/* Values of libmodbus' MODBUS_RTU_RTS_* (checked in mb_rtu.c). */
enum conf_rts { CONF_RTS_NONE = 0, CONF_RTS_UP = 1, CONF_RTS_DOWN = 2 };
#define CONF_RTS_DELAY_US_MAX 100000 /* the loop sleeps it twice a reply */
#define CONF_RS485_DELAY_MS_MAX 100  /* the kernel's RS485_MAX_RTS_DELAY */

struct conf_model {
    int id;            /* 0..254, model id on the serial links */
    int unit;          /* Modbus unit id 1..247 */
    int kind;          /* CONF_KIND_* (models.h enum model_kind) */
    int n, m;          /* bezier: degrees 1..7; bspline: intervals 1..255 (its storage) */
    unsigned flags;    /* IT2N_F_* */
    int preload;       /* 1: the paper's 4x4 example data set */
    int write_protect; /* 1: no Modbus write may change it (links may) */
    int removed;       /* parsing only: removed = yes moves the id to conf.removed */
    unsigned set;      /* CONF_SET_*: the keys the file gives (not defaults) */
};

/* Keys of [model:ID] that change its shape (a change clears its points):
 * a reload applies such a change to a model holding data only when the
 * file gives the key, never from a default (a line lost in a rewrite). */
#define CONF_SET_N 1u
#define CONF_SET_M 2u
#define CONF_SET_Z 4u
#define CONF_SET_TYPE1 8u
#define CONF_SET_CHORD 16u
#define CONF_SET_KIND 32u

/* [model:ID] kind (the values of models.h enum model_kind). */
#define CONF_KIND_BEZIER 0
#define CONF_KIND_BSPLINE 1

enum conf_link_type { CONF_LINK_SERIAL = 0, CONF_LINK_USB = 1 };

struct conf_link {
    char name[CONF_NAME];
    int type;
    char device[CONF_PATH]; /* serial */
    int baud;
    uint16_t vid, pid;   /* usb */
    char serial[64];     /* usb, optional */
    int rto_ms;          /* first retransmission timeout; 0 = from baud */
    int peer_timeout_ms; /* unanswered this long: link declared down */
    int device_line;     /* config line of device, for conflicts */
};

/* [metrics] listen: the Prometheus endpoint (daemon/metrics.c). */
struct conf_metrics {
    char host[64];
    char port[8]; /* "" = off (the default) */
    int line;     /* config line of listen, 0 built-in or a flag */
};

struct conf {
    char state_dir[CONF_PATH];
    int snapshot_interval; /* s */
    int fsync;             /* 1: fsync the WAL before acknowledging */
    int io;                /* enum loop_io (daemon/loop.h): auto, io_uring, epoll */
    int max_models;
    struct conf_listen listen[CONF_MAX_LISTEN];
    int nlisten;
    int max_clients;
    int max_pending;      /* TCP connections without a slot (no complete request yet) */
    int idle_timeout;     /* s */
    int byte_timeout;     /* ms */
    int tcp_keepalive;    /* s idle before keepalive probes, 0 off */
    int evict_idle;       /* ms without a request before a slot may be taken */
    int word_order;       /* enum it2n_regmap_order */
    int int32_word_order; /* of u32/i32 registers; -1: as word_order */
    int default_model;    /* TCP units 0, 255: model id, or CONF_DEFAULT_* */
    int coord_scale;
    int grid_rows, grid_cols;
    struct conf_rtu rtu[CONF_MAX_RTU];
    int nrtu;
    struct conf_model model[CONF_MAX_MODELS];
    int nmodels;
    /* [model:ID] sections with removed = yes: the operator's explicit
     * consent to discard the data of these ids (never in model[]). */
    int removed[CONF_MAX_MODELS];
    int nremoved;
    struct conf_link link[CONF_MAX_LINKS];
    int nlinks;
    int link_backoff_max; /* s */
    char user[CONF_NAME]; /* "" = keep the starting user          */
    unsigned uid, gid;    /* resolved from user at load           */
    struct spb_conf spb;  /* [sparkplug] (spb_conf.h)             */
    struct conf_metrics metrics;
};

#define CONF_DEFAULT_AUTO (-1) /* the only model, when exactly one is configured */
#define CONF_DEFAULT_NONE (-2) /* units 0 and 255 answer exception 0B */

/* The unit that Modbus TCP unit ids 0 and 255 reach under c's
 * default_model, or 0 for none. */
int conf_default_unit(const struct conf *c);

/* Fill c with the built-in default (TCP 127.0.0.1:1502, model 1 on unit 1
 * preloaded with the paper data set, state in ./state). */
void conf_default(struct conf *c);

/* Load path over the defaults. On error returns -1 and writes
 * "file:line: [section] key: reason" into err. c is only written on
 * success. The file is read whole before parsing, never blocking: it must
 * be a regular file (a FIFO, a device or a directory is refused without
 * reading it) of 1..CONF_MAX_BYTES bytes whose last line ends with a
 * newline (a file cut short by a non-atomic rewrite almost always ends
 * mid-line) and that sets at least one key. */
#define CONF_MAX_BYTES (1024 * 1024)
int conf_load(struct conf *c, const char *path, char *err, size_t errsize);

/* Resolve every listener's host as the listener will (getaddrinfo, passive,
 * numeric port), so a misspelt host name fails --check-config, start and
 * reload with "file:line: [section] key: cannot resolve host 'H': reason"
 * instead of at bind time. Kept out of conf_load so parsing (and its
 * fuzzer) never waits for DNS. Returns 0 or -1 with err written. */
int conf_check_hosts(const struct conf *c, const char *path, char *err, size_t errsize);

/* Command-line settings that override the file (it2nd --listen,
 * --state-dir, --metrics): the common case without a configuration file.
 * listen[] replaces every TCP listener of the file ([modbus] tcp_listen
 * and [listen:NAME] sections, their access policy included). */
struct conf_override {
    const char *listen[CONF_MAX_LISTEN];
    int nlisten;
    const char *state_dir; /* NULL: the file's */
    const char *metrics;   /* NULL: the file's; "none": off */
};

/* Apply o over c (after conf_default/conf_load) and check what the flags
 * change as the file's keys are checked. Returns 0, or -1 with
 * "--flag 'VALUE': reason" in err and c unchanged. */
int conf_apply_override(struct conf *c, const struct conf_override *o, char *err, size_t errsize);

/* One key of a section kind ("sparkplug", "rtu:a", ...) into that
 * section's struct at base (a struct spb_conf, a struct conf_rtu, ...),
 * read as conf_load reads it; line is kept where the section keeps lines.
 * For tests of a section's own structs. 0, or -1 with the reason in err
 * (without file, line or key). */
int conf_key(void *base, const char *section, const char *name, const char *value, int line, char *err, size_t errsize);

/* Whether c removes model id with removed = yes. */
int conf_removes(const struct conf *c, int id);

/* Two [rtu:]/[link:] sections on one device: one of them would fail at
 * run time ("locked by another process"). conf_load refuses identical
 * paths; this also compares what the paths name (stat: same inode, or the
 * same character device through another node), so a symlink such as
 * /dev/serial/by-id/... is caught. Paths that do not exist yet are
 * skipped (a device may be plugged in later). Kept out of conf_load like
 * conf_check_hosts. Returns 0 or -1 with "file:line: [section] device:
 * ..." naming both sections in err. */
int conf_check_devices(const struct conf *c, const char *path, char *err, size_t errsize);

/* Whether two [rtu:] (or [link:]) sections say the same, wherever they
 * stand in the file: a reload reopens a port or link only when its
 * section changed, not when a line above it moved it (device_line is
 * where, not what). 1 or 0. */
int conf_rtu_same(const struct conf_rtu *a, const struct conf_rtu *b);
int conf_link_same(const struct conf_link *a, const struct conf_link *b);

#endif
