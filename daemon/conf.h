/* conf — it2nd configuration: built-in defaults, INI file (libinih), and
 * validation. Every key is documented in docs/daemon.md and
 * daemon/it2nd.conf.example. */
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

struct conf_listen {
    char host[64];
    char port[8];
};

struct conf_rtu {
    char name[CONF_NAME];
    char device[CONF_PATH];
    int baud;
    char parity;      /* 'N', 'E', 'O' */
    int stop_bits;    /* 1 or 2 */
    int rs485;        /* 1: TIOCSRS485 RS-485 mode */
};

struct conf_model {
    int id;           /* 0..254, model id on the serial links */
    int unit;         /* Modbus unit id 1..247 */
    int n, m;
    unsigned flags;   /* IT2N_F_* */
    int preload;      /* 1: the paper's 4x4 example data set */
};

enum conf_link_type { CONF_LINK_SERIAL = 0, CONF_LINK_USB = 1 };

struct conf_link {
    char name[CONF_NAME];
    int type;
    char device[CONF_PATH];  /* serial */
    int baud;
    uint16_t vid, pid;       /* usb */
    char serial[64];         /* usb, optional */
};

struct conf {
    char state_dir[CONF_PATH];
    int snapshot_interval;   /* s */
    int fsync;               /* 1: fsync the WAL before acknowledging */
    int max_models;
    struct conf_listen listen[CONF_MAX_LISTEN];
    int nlisten;
    int max_clients;
    int idle_timeout;        /* s */
    int byte_timeout;        /* ms */
    int word_order;          /* enum it2n_regmap_order */
    int coord_scale;
    int grid_rows, grid_cols;
    struct conf_rtu rtu[CONF_MAX_RTU];
    int nrtu;
    struct conf_model model[CONF_MAX_MODELS];
    int nmodels;
    struct conf_link link[CONF_MAX_LINKS];
    int nlinks;
    int link_backoff_max;    /* s */
    char user[CONF_NAME];    /* "" = keep the starting user          */
    unsigned uid, gid;       /* resolved from user at load           */
};

/* Fill c with the built-in default (TCP 127.0.0.1:1502, model 1 on unit 1
 * preloaded with the paper data set, state in ./state). */
void conf_default(struct conf *c);

/* Load path over the defaults. On error returns -1 and writes
 * "file:line: [section] key: reason" into err. c is only written on
 * success. */
int conf_load(struct conf *c, const char *path, char *err, size_t errsize);

#endif
