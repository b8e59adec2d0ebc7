/*
 * it2n — protocol messages: plain structs and their pack/unpack.
 *
 * Every multi-byte field is little-endian. Values are fixed point:
 * coordinates, memberships and results are int64 Q24 (it2n_val, raw/2^24;
 * a PUT with IT2N_PUT_FINE carries its memberships in Q30, raw/2^30);
 * parameters u, w are uint32 Q2.30 on the wire (1.0 = 0x40000000). Unpacked
 * structs hold it2n_val directly so the daemon can hand them to the core.
 * Byte layouts: docs/protocol.md.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#ifndef IT2N_MSG_H
#define IT2N_MSG_H

#include "it2n_proto.h"

enum it2n_msg_type {
    IT2N_MSG_HELLO = 0x01,      /* version, capabilities, limits          */
    IT2N_MSG_CONFIGURE = 0x02,  /* model kind, sizes and flags            */
    IT2N_MSG_PUT = 0x03,        /* batch of grid point footprints         */
    IT2N_MSG_COMMIT = 0x04,     /* solve the model                        */
    IT2N_MSG_QUERY = 0x05,      /* evaluate at (u, w)                     */
    IT2N_MSG_LOCATE = 0x06,     /* find (u, w) for (x, y)                 */
    IT2N_MSG_SAMPLE = 0x07,     /* evaluate on a rows x cols grid         */
    IT2N_MSG_GET_NET = 0x08,    /* control net of one footprint           */
    IT2N_MSG_GET_STATUS = 0x09, /* model status                           */
    IT2N_MSG_RESET = 0x0A,      /* forget a model (0xFF: all)             */
    IT2N_MSG_EVENT = 0x10,      /* model changed (daemon -> subscribers)  */
    IT2N_MSG_ACK = 0x20,        /* reliable frame accepted (and durable)  */
    IT2N_MSG_NACK = 0x21,       /* reliable frame refused, with reason    */
    IT2N_MSG_GAP = 0x22,        /* v1.1: receiver misses a frame, holds later ones */
    IT2N_MSG_RCVD = 0x23,       /* v1.2: frame received, its answer pending */
    IT2N_MSG_QUERY_RESULT = 0x45,
    IT2N_MSG_LOCATE_RESULT = 0x46,
    IT2N_MSG_SAMPLE_DATA = 0x47,
    IT2N_MSG_NET_ROW = 0x48,
    IT2N_MSG_STATUS = 0x49
};

/* Responses are the request type | 0x40 and echo the request seq in `re`. */
#define IT2N_MSG_RESPONSE 0x40u

/* Model id addressing every model (RESET only). */
#define IT2N_MODEL_ALL 0xFFu

/* HELLO capability bits. */
#define IT2N_CAP_INSTRUMENT 0x01u /* produces data (PUT/COMMIT)          */
#define IT2N_CAP_SERVER 0x02u     /* solves and answers queries          */
#define IT2N_CAP_Z 0x04u          /* supports IT2N_F_Z                   */
#define IT2N_CAP_CHORD 0x08u      /* supports IT2N_F_CHORD               */
#define IT2N_CAP_TYPE1 0x10u      /* supports IT2N_F_TYPE1               */
#define IT2N_CAP_EVENTS 0x20u     /* sends EVENT on model change         */
/* v1.3: the sender speaks protocol v1.3 (docs/protocol.md 5.3): it reads
 * the 5-byte CONFIGURE with a model kind, and PUT indices up to 255. A
 * client sends the B-spline CONFIGURE only to a server announcing it. */
#define IT2N_CAP_BSPLINE 0x40u
/* v1.3: the server reads PUT flag IT2N_PUT_FINE (memberships in Q30,
 * docs/protocol.md 5.4). A client sends that flag only to a server
 * announcing it; an older server refuses it (FIELD, offset 1). */
#define IT2N_CAP_FINE 0x80u

/* Protocol revision of the messages (docs/protocol.md 6): 1.3 changes
 * section 5 only (the 5-byte CONFIGURE, PUT FINE); frames stay wire
 * version 3. */
#define IT2N_PROTO_REVISION_MINOR 3

/* PUT flags. */
#define IT2N_PUT_REPLACE 0x01u /* overwrite entries already present */
/* v1.3: T, I, F of every entry are Q30 (IT2N_MEMB_FRAC, 1.0 = 2^30), the
 * core's fine layout, so a membership keeps 2^-30 over the wire. Only to
 * a server whose HELLO set IT2N_CAP_FINE. */
#define IT2N_PUT_FINE 0x02u
/* PUT flags this codec reads. */
#define IT2N_PUT_FLAGS (IT2N_PUT_REPLACE | IT2N_PUT_FINE)

/* Wire sizes. */
#define IT2N_PUT_HDR 4u
#define IT2N_PUT_ENTRY (4u + 8u * IT2N_CH_COUNT)
#define IT2N_SAMPLE_HDR 13u
#define IT2N_SAMPLE_POINT (8u * IT2N_CH_COUNT)
#define IT2N_NET_ROW_HDR 7u

/* Most entries in one PUT / points in one SAMPLE_DATA (payload-bound). */
#define IT2N_PUT_MAX                                                 \
    ((IT2N_PROTO_MAX_PAYLOAD - IT2N_PUT_HDR) / IT2N_PUT_ENTRY > 255u \
         ? 255u                                                      \
         : (IT2N_PROTO_MAX_PAYLOAD - IT2N_PUT_HDR) / IT2N_PUT_ENTRY)
#define IT2N_SAMPLE_MAX                                                    \
    ((IT2N_PROTO_MAX_PAYLOAD - IT2N_SAMPLE_HDR) / IT2N_SAMPLE_POINT > 255u \
         ? 255u                                                            \
         : (IT2N_PROTO_MAX_PAYLOAD - IT2N_SAMPLE_HDR) / IT2N_SAMPLE_POINT)

/* Q2.30 wire parameter, 1.0 = 0x40000000. */
#define IT2N_WIRE_PAR_ONE 0x40000000u

/* Q32 it2n_par -> Q2.30 wire, rounded to nearest; clamps to [0, 1]. */
uint32_t it2n_par_to_wire(it2n_par p);
/* Q2.30 wire -> Q32 it2n_par (exact: shift by 2). */
it2n_par it2n_par_from_wire(uint32_t w);

/* Smallest max_payload a HELLO may announce (an ACK/NACK, a SAMPLE_DATA
 * of one point and every request fit). */
#define IT2N_HELLO_MIN_PAYLOAD 64u

typedef struct it2n_msg_hello {
    uint8_t version_min, version_max; /* protocol versions spoken      */
    uint8_t max_degree;               /* IT2N_MAX_DEGREE of the sender */
    uint8_t window;                   /* IT2N_PROTO_WINDOW, >= 1       */
    uint32_t caps;                    /* IT2N_CAP_*                    */
    uint16_t max_payload;             /* IT2N_PROTO_MAX_PAYLOAD, >= 64 */
    uint16_t max_models;              /* model ids the sender serves   */
    char node[16];                    /* name, NUL-padded, not terminated if 16 long */
} it2n_msg_hello;

/* CONFIGURE model kinds (v1.3). */
enum it2n_cfg_kind {
    IT2N_CFG_BEZIER = 0, /* 4-byte CONFIGURE (every version): degrees 1..7 */
    IT2N_CFG_BSPLINE = 1 /* 5-byte CONFIGURE (v1.3): cubic not-a-knot
                            B-spline, n x m intervals, 1..255 each      */
};

/* Payload bytes of the v1.3 CONFIGURE that names a kind. */
#define IT2N_CONFIGURE13_LEN 5u

typedef struct it2n_msg_configure {
    uint8_t model, n, m, flags; /* Bezier: degrees 1..IT2N_MAX_DEGREE;
                                   B-spline: intervals 1..255; IT2N_F_*  */
    uint8_t kind;               /* enum it2n_cfg_kind: 0 packs as the
                                   4-byte v1.1/v1.2 CONFIGURE, 1 as the
                                   5-byte v1.3 one                      */
} it2n_msg_configure;

typedef struct it2n_put_entry {
    uint8_t i, j, fp;             /* grid point (0..255: the model's n, m
                                       bound it), footprint (enum it2n_fp) */
    it2n_val vals[IT2N_CH_COUNT]; /* x, y, z, T, I, F in Q24; T, I, F in
                                       Q30 with IT2N_PUT_FINE              */
} it2n_put_entry;

typedef struct it2n_msg_put {
    uint8_t model, flags, count; /* flags: IT2N_PUT_*; count 1..IT2N_PUT_MAX */
    it2n_put_entry e[IT2N_PUT_MAX];
} it2n_msg_put;

typedef struct it2n_msg_model {
    uint8_t model; /* COMMIT, GET_STATUS, RESET */
} it2n_msg_model;

typedef struct it2n_msg_query {
    uint8_t model;
    uint32_t u, w; /* Q2.30, <= IT2N_WIRE_PAR_ONE */
} it2n_msg_query;

typedef struct it2n_msg_locate {
    uint8_t model;
    it2n_val x, y; /* Q24 */
} it2n_msg_locate;

typedef struct it2n_msg_sample {
    uint8_t model, fp;
    uint16_t rows, cols; /* each >= 2 */
} it2n_msg_sample;

typedef struct it2n_msg_get_net {
    uint8_t model, fp;
} it2n_msg_get_net;

/* EVENT kinds. */
enum it2n_event_kind {
    IT2N_EV_CONFIGURED = 1,
    IT2N_EV_UPDATED = 2,
    IT2N_EV_SOLVED = 3,
    IT2N_EV_RESET = 4,
    IT2N_EV_ERROR = 5,
    /* v1.1: the sender declared the link down and dropped frames it could
     * not deliver: model 0xFF, code IT2N_PROTO_ERR_DOWN, generation = the
     * number of reliable frames dropped. */
    IT2N_EV_LOST = 6
};

typedef struct it2n_msg_event {
    uint8_t model, kind; /* enum it2n_event_kind           */
    int16_t code;        /* error code for IT2N_EV_ERROR   */
    uint32_t generation; /* it2n_model.generation after it */
} it2n_msg_event;

typedef struct it2n_msg_ack {
    uint16_t seq; /* sequence number acknowledged */
    /* v1.2 ACK only: bit k set = frame seq - 1 - k was ACKed too (a lost
     * ACK is covered by the next one). Packed as 10 bytes when non-zero,
     * else as the 2-byte ACK. Always 0 in RCVD. */
    uint64_t acked;
} it2n_msg_ack;

/* Payload bytes of a v1.2 ACK that names earlier ACKed frames. */
#define IT2N_ACK12_LEN 10u

/* GAP (v1.1, unreliable): the receiver misses `seq` and has just kept
 * `have`, a later frame. v1.2 adds `held` (selective acknowledgement,
 * docs/protocol.md 4.3 rule 4): bit k set = frame seq + 1 + k is held by
 * the receiver; never 0 in v1.2 (`have` is one of them). Packed as 12
 * bytes when held != 0, else as the 4-byte v1.1 GAP. */
typedef struct it2n_msg_gap {
    uint16_t seq, have;
    uint64_t held;
} it2n_msg_gap;

/* Payload bytes of a v1.2 GAP (seq, have, held). */
#define IT2N_GAP12_LEN 12u

typedef struct it2n_msg_nack {
    uint16_t seq;           /* sequence number refused                       */
    int16_t code;           /* enum it2n_error or enum it2n_proto_error      */
    int16_t i, j;           /* grid point, or -1 (as it2n_errinfo)           */
    int8_t fp, ch;          /* footprint, channel, or -1                     */
    it2n_val value, lo, hi; /* offending value and accepted range   */
} it2n_msg_nack;

typedef struct it2n_msg_query_result {
    uint16_t re;
    uint8_t model;
    uint32_t u, w;         /* Q2.30 as queried                 */
    uint32_t out_of_range; /* as it2n_point.out_of_range       */
    it2n_val v[IT2N_FP_COUNT][IT2N_CH_COUNT];
    it2n_summary sum;
} it2n_msg_query_result;

typedef struct it2n_locate_wire {
    uint32_t u, w;     /* Q2.30                      */
    uint8_t status;    /* enum it2n_loc_status       */
    it2n_val residual; /* Q24                        */
    it2n_val v[IT2N_CH_COUNT];
} it2n_locate_wire;

typedef struct it2n_msg_locate_result {
    uint16_t re;
    uint8_t model;
    it2n_val x, y;
    it2n_locate_wire fp[IT2N_FP_COUNT];
} it2n_msg_locate_result;

typedef struct it2n_msg_sample_data {
    uint16_t re;
    uint8_t model, fp;
    uint16_t rows, cols;
    uint32_t start; /* row-major index of the first point, < rows*cols */
    uint8_t count;  /* 1..IT2N_SAMPLE_MAX, start+count <= rows*cols     */
    it2n_val v[IT2N_SAMPLE_MAX][IT2N_CH_COUNT];
} it2n_msg_sample_data;

typedef struct it2n_msg_net_row {
    uint16_t re;
    uint8_t model, fp, n, m, row; /* row 0..n; m+1 control points */
    it2n_val v[IT2N_DIM][IT2N_CH_COUNT];
} it2n_msg_net_row;

/* Model states in STATUS. */
enum it2n_model_state { IT2N_MS_EMPTY = 0, IT2N_MS_COLLECTING = 1, IT2N_MS_SOLVED = 2, IT2N_MS_ERROR = 3 };

typedef struct it2n_msg_status {
    uint16_t re;
    uint8_t model, state, n, m, flags; /* state: enum it2n_model_state */
    uint16_t missing;                  /* entries still absent         */
    uint32_t generation;
    int16_t last_error;
} it2n_msg_status;

/* One message of any type: `type` selects the union member. */
typedef struct it2n_msg {
    uint8_t type; /* enum it2n_msg_type */
    union {
        it2n_msg_hello hello;
        it2n_msg_configure configure;
        it2n_msg_put put;
        it2n_msg_model model; /* COMMIT, GET_STATUS, RESET */
        it2n_msg_query query;
        it2n_msg_locate locate;
        it2n_msg_sample sample;
        it2n_msg_get_net get_net;
        it2n_msg_event event;
        it2n_msg_ack ack;
        it2n_msg_gap gap;
        it2n_msg_ack rcvd; /* RCVD: the frame received, answer pending */
        it2n_msg_nack nack;
        it2n_msg_query_result query_result;
        it2n_msg_locate_result locate_result;
        it2n_msg_sample_data sample_data;
        it2n_msg_net_row net_row;
        it2n_msg_status status;
    } u;
} it2n_msg;

/*
 * Serialise msg into buf (capacity cap). Validates every field with the same
 * rules as it2n_msg_unpack, so what packs also unpacks. Returns the payload
 * length, IT2N_PROTO_ERR_TYPE, IT2N_PROTO_ERR_FIELD or
 * IT2N_PROTO_ERR_NOSPACE; err (may be NULL) says which field.
 */
#define it2n_msg_pack IT2N_PROTO_ABI(it2n_msg_pack)
int it2n_msg_pack(const it2n_msg *msg, uint8_t *buf, size_t cap, it2n_proto_errinfo *err);

/*
 * Parse len payload bytes of a frame of `type` into *msg. Checks the exact
 * length for the type (and the counts inside it) and every enumerated or
 * bounded field; value ranges that depend on a model (coordinate limit,
 * memberships in [0,1], i <= n) are the core's job. Returns IT2N_OK,
 * IT2N_PROTO_ERR_TYPE, _PAYLOAD or _FIELD with err filled (may be NULL);
 * on error *msg is unspecified.
 */
#define it2n_msg_unpack IT2N_PROTO_ABI(it2n_msg_unpack)
int it2n_msg_unpack(uint8_t type, const uint8_t *p, size_t len, it2n_msg *msg, it2n_proto_errinfo *err);

/* Session id carried by the SYN golden vector (00_hello) and by the v1.2
 * ones (every v1.2 payload starts with the session). */
#define IT2N_VECTOR_SESSION 0x1D2C3B4Au

/* Number of golden vectors: one per message type in v1.1 (wire version 2),
 * the v1.3 B-spline CONFIGURE (19, in either wire version), then the v1.2
 * forms (wire version 3) a v1.1 vector does not show: GAP with its held
 * bitmap, ACK naming earlier ACKs, RCVD; then the v1.3 PUT FINE (23, Q30
 * memberships, framed in version 3). */
#define IT2N_VECTOR_COUNT 24u
/* The first v1.2 golden vector: k >= this is framed in version 3. */
#define IT2N_VECTOR_FIRST_V12 20u

/*
 * Golden vector k (0..IT2N_VECTOR_COUNT-1): fills the frame header and the
 * message whose encoding is protocol/vectors/<NN>_<name>.hex (the payload of
 * a SYN frame and of every v1.2 frame, hdr->version IT2N_PROTO_VERSION_12,
 * is IT2N_VECTOR_SESSION, u32 little-endian, then the message) and returns
 * the name ("hello"), or NULL when k is out of range. Code, not a table, so
 * flash holds a few hundred bytes instead of 18 message structs.
 */
#define it2n_proto_vector IT2N_PROTO_ABI(it2n_proto_vector)
const char *it2n_proto_vector(unsigned k, it2n_frame_hdr *hdr, it2n_msg *msg);

/* Name of a message type ("PUT"), or NULL if unknown. */
const char *it2n_msg_name(uint8_t type);

#endif /* IT2N_MSG_H */
