/*
 * it2nctl — client for a running it2nd. The commands (ctl_main.c) talk to
 * the daemon through one of two transports with the same interface:
 *   ctl_modbus.c  Modbus TCP or RTU (libmodbus), docs/registers.md
 *   ctl_link.c    the framing protocol on a serial line or pty
 *                 (protocol/ API, docs/protocol.md)
 * A transport prints its own message on a failure and returns an exit
 * status (CTL_EXIT_*); nothing is printed on success.
 */
#ifndef IT2N_CTL_H
#define IT2N_CTL_H

#include "cli.h"
#include "it2n.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Exit statuses: those of it2n (cli.h) plus the connection failures. */
enum {
    CTL_EXIT_OK = 0,
    CTL_EXIT_USAGE = 1, /* bad command line                                */
    CTL_EXIT_DATA = 2,  /* bad DATA.csv, or the daemon refused the request */
    CTL_EXIT_COMM = 3   /* daemon unreachable, no answer, link failure     */
};

/* Model state, numbered as the status register (IT2N_REGMAP_STATE_*). */
enum { CTL_ST_EMPTY = 0, CTL_ST_INCOMPLETE, CTL_ST_SOLVED, CTL_ST_FAILED };

typedef struct ctl_status {
    unsigned model;       /* model id (links) / model_id register */
    int state;            /* CTL_ST_*                              */
    unsigned n, m, flags; /* configured degrees and IT2N_F_*       */
    unsigned present, required;
    uint32_t generation;
    int last_error;              /* it2n error code, 0 none               */
    unsigned kind;               /* 0 Bezier, 1 B-spline (IT2N_REGMAP_KIND_*)    */
    unsigned net_rows, net_cols; /* of each solved net, 0 unsolved */
} ctl_status;

/* Locate status of one footprint. Modbus has one bit per footprint
 * (inside or not), so CTL_LOC_NOT_INSIDE stands for outside-or-noconv. */
enum { CTL_LOC_INSIDE = 0, CTL_LOC_OUTSIDE, CTL_LOC_NOCONV, CTL_LOC_NOT_INSIDE };

typedef struct ctl_loc {
    bool has_uw; /* u, w known (links; not in the register map) */
    it2n_par u, w;
    int status; /* CTL_LOC_*                              */
    it2n_val v[IT2N_CH_COUNT];
} ctl_loc;

/* Control nets: ctrl[fp][i][j][ch] in Q24. */
typedef it2n_val ctl_net[IT2N_FP_COUNT][IT2N_DIM][IT2N_DIM][IT2N_CH_COUNT];

/* Push progress: entries done of total. */
typedef void (*ctl_progress_fn)(void *ctx, unsigned done, unsigned total);

/* A sample node: every footprint's channels (only fps of the model are
 * filled) and the out-of-range bits as it2n_point.out_of_range. */
typedef int (*ctl_sample_fn)(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w, const it2n_point *pt);

/* Return value of push when the daemon refused one data point: *rej names
 * it (i, j, fp, ch, value) so the caller can print FILE:LINE. */
#define CTL_REJECTED 100

typedef struct ctl_ops {
    const char *kind; /* "modbus" or "link" */
    int (*status)(void *c, ctl_status *st);
    /* Configure (kind, n, m, flags), clear, upload every entry of src,
     * commit. Checks what the transport cannot carry before sending
     * anything (returns CTL_REJECTED with *rej, ch >= 0, code
     * IT2N_ERR_RANGE). */
    int (*push)(void *c, const cli_data *src, ctl_progress_fn progress, void *pctx, it2n_errinfo *rej);
    /* Evaluate at (*u, *w); on return *u, *w are the parameters the
     * daemon evaluated at (a transport may round them). */
    int (*eval)(void *c, it2n_par *u, it2n_par *w, it2n_point *pt);
    /* Locate (*x, *y) on every footprint (*x, *y as used by the daemon). */
    int (*locate)(void *c, it2n_val *x, it2n_val *y, ctl_loc res[IT2N_FP_COUNT]);
    /* Control nets of the solved model described by st. */
    int (*net)(void *c, const ctl_status *st, ctl_net *net);
    /* Every footprint on a rows x cols grid, row-major. */
    int (*sample)(void *c, const ctl_status *st, unsigned rows, unsigned cols, ctl_sample_fn cb, void *ctx);
    /* Wait up to timeout_ms for the generation to differ from gen; fills
     * *st. Returns CTL_EXIT_OK (changed or not: compare st->generation). */
    int (*wait)(void *c, uint32_t gen, int timeout_ms, ctl_status *st);
    void (*close)(void *c);
    /* The B-spline kind (NULL: the transport cannot carry it): read row
     * `row` of net (fp, ch), st->net_cols coefficients in Q24, into out. */
    int (*coef_row)(void *c, const ctl_status *st, unsigned fp, unsigned ch, unsigned row, it2n_val *out);
} ctl_ops;

/* Connection options from the command line. */
typedef struct ctl_conn_opts {
    const char *tcp;     /* HOST[:PORT], default 127.0.0.1:1502          */
    const char *rtu;     /* serial device for Modbus RTU                 */
    const char *link;    /* serial device / pty for the framing protocol */
    unsigned unit;       /* Modbus unit id (default 1)                   */
    unsigned model;      /* link model id (default 1)                    */
    unsigned baud;       /* RTU / link baud rate                         */
    char parity;         /* RTU: 'N', 'E', 'O'                           */
    unsigned stop_bits;  /* RTU: 1 or 2                                  */
    unsigned timeout_ms; /* per request                                  */
    int poll_ms;         /* watch: Modbus polling interval               */
    const char *broker;  /* it2nctl spb: MQTT broker HOST[:PORT]         */
    const char *group;   /* it2nctl spb: Sparkplug group_id              */
    const char *node;    /* it2nctl spb: Sparkplug edge_node_id          */
} ctl_conn_opts;

/* Split a --tcp argument, HOST:PORT or [V6]:PORT (HOST alone: port 1502),
 * into host[hn] and port[pn]. Returns NULL when it is well formed, else
 * what is wrong with it (a usage error: the port is not 1..65535, the host
 * is empty, a bracket is not closed); checks syntax only, no name lookup. */
const char *ctl_tcp_split(const char *t, char *host, size_t hn, char *port, size_t pn);

/* Open a transport; on failure prints why and returns NULL with *rc set. */
void *ctl_modbus_open(const ctl_conn_opts *o, const ctl_ops **ops, int *rc);
void *ctl_link_open(const ctl_conn_opts *o, const ctl_ops **ops, int *rc);
/* Sparkplug B (ctl_spb.c): status and eval of device model-<o->model> of
 * edge node o->node through its DCMD query, via the broker o->broker. */
void *ctl_spb_open(const ctl_conn_opts *o, const ctl_ops **ops, int *rc);

/* `it2nctl spb watch ARGS` (argv[0] = "watch"): the births and deaths of a
 * Sparkplug group, one CSV line each. Returns the exit status. */
int ctl_spb_watch(int argc, char **argv);

/* Grid parameter k / (count - 1) in Q32, as it2n_sample computes it. */
static inline it2n_par ctl_grid_par(unsigned k, unsigned count)
{
    uint64_t d = count - 1u;
    return (it2n_par)((((uint64_t)k << IT2N_PAR_FRAC) + d / 2u) / d);
}

/* Interval summary and out-of-range bits of pt from its values, as the
 * core's it2n_eval computes them (for transports that send values only). */
void ctl_summarise(bool type1, it2n_point *pt);

/* Name of a model state ("solved"). */
const char *ctl_state_name(int state);

/* A push refused because the daemon's model (named by where: "unit 3",
 * the link's "DEVICE model 1") is of the other kind than src: says so and
 * how to push, "(nothing was <nothing>)". Returns CTL_EXIT_DATA. */
int ctl_wrong_kind(const char *where, bool held_bspline, const cli_data *src, const char *nothing);

#endif /* IT2N_CTL_H */
