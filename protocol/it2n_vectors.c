/*
 * The messages behind the golden vectors in protocol/vectors/. Values are
 * chosen to exercise signs, zeros (so COBS has work) and every field.
 * Changing anything here changes the wire vectors: run `make proto-vectors`
 * and review the diff.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include <string.h>

#include "it2n_msg.h"

/* A deterministic, varied Q24 value for slot k (both signs, some zeros). */
static it2n_val vv(unsigned k)
{
    int64_t base = (int64_t)((k * 2654435761u) % 200003u) - 100001;
    return (k % 5u == 0u) ? 0 : base * 1677; /* ~ +-10 units in Q24 */
}

static void vals(it2n_val *v, size_t n, unsigned seed)
{
    size_t k;
    for (k = 0; k < n; k++)
        v[k] = vv(seed + (unsigned)k);
}

static void fill(unsigned k, it2n_msg *m)
{
    unsigned a, b;
    switch (k) {
    case 0:
        m->type = IT2N_MSG_HELLO;
        m->u.hello.version_min = IT2N_PROTO_VERSION_MIN;
        m->u.hello.version_max = IT2N_PROTO_VERSION;
        m->u.hello.max_degree = 7;
        m->u.hello.window = 4;
        m->u.hello.caps = IT2N_CAP_INSTRUMENT | IT2N_CAP_Z | IT2N_CAP_TYPE1;
        m->u.hello.max_payload = 1024;
        m->u.hello.max_models = 1;
        memcpy(m->u.hello.node, "inst-0001", 9);
        break;
    case 1:
        m->type = IT2N_MSG_CONFIGURE;
        m->u.configure.model = 2;
        m->u.configure.n = 3;
        m->u.configure.m = 3;
        m->u.configure.flags = IT2N_F_CHORD;
        break;
    case 2:
        m->type = IT2N_MSG_PUT;
        m->u.put.model = 2;
        m->u.put.count = 2;
        m->u.put.e[0].i = 0;
        m->u.put.e[0].j = 1;
        m->u.put.e[0].fp = IT2N_FP_LL;
        /* x = -23, y = 1, T = 0.9 (rounded Q24), I = 0.3, F = 0.1 */
        m->u.put.e[0].vals[IT2N_CH_X] = -23 * IT2N_VAL_ONE;
        m->u.put.e[0].vals[IT2N_CH_Y] = IT2N_VAL_ONE;
        m->u.put.e[0].vals[IT2N_CH_T] = 15099494;
        m->u.put.e[0].vals[IT2N_CH_I] = 5033165;
        m->u.put.e[0].vals[IT2N_CH_F] = 1677722;
        m->u.put.e[1] = m->u.put.e[0];
        m->u.put.e[1].fp = IT2N_FP_RR;
        m->u.put.e[1].vals[IT2N_CH_X] = -11 * IT2N_VAL_ONE;
        m->u.put.e[1].vals[IT2N_CH_Y] = 13 * IT2N_VAL_ONE;
        break;
    case 3:
        m->type = IT2N_MSG_COMMIT;
        m->u.model.model = 2;
        break;
    case 4:
        m->type = IT2N_MSG_QUERY;
        m->u.query.model = 2;
        m->u.query.u = IT2N_WIRE_PAR_ONE / 2u;
        m->u.query.w = IT2N_WIRE_PAR_ONE;
        break;
    case 5:
        m->type = IT2N_MSG_LOCATE;
        m->u.locate.model = 2;
        m->u.locate.x = -17 * IT2N_VAL_ONE;
        m->u.locate.y = IT2N_VAL_ONE / 2;
        break;
    case 6:
        m->type = IT2N_MSG_SAMPLE;
        m->u.sample.model = 2;
        m->u.sample.fp = IT2N_FP_D;
        m->u.sample.rows = 11;
        m->u.sample.cols = 300;
        break;
    case 7:
        m->type = IT2N_MSG_GET_NET;
        m->u.get_net.model = 2;
        m->u.get_net.fp = IT2N_FP_R;
        break;
    case 8:
        m->type = IT2N_MSG_GET_STATUS;
        m->u.model.model = 2;
        break;
    case 9:
        m->type = IT2N_MSG_RESET;
        m->u.model.model = IT2N_MODEL_ALL;
        break;
    case 10:
        m->type = IT2N_MSG_EVENT;
        m->u.event.model = 2;
        m->u.event.kind = IT2N_EV_SOLVED;
        m->u.event.code = 0;
        m->u.event.generation = 0x01020304u;
        break;
    case 19:
        /* v1.3: the 5-byte CONFIGURE of a B-spline model, 64 x 48
         * intervals (65 x 49 points: both sizes beyond the Bezier 7),
         * with z */
        m->type = IT2N_MSG_CONFIGURE;
        m->u.configure.model = 2;
        m->u.configure.n = 64;
        m->u.configure.m = 48;
        m->u.configure.flags = IT2N_F_Z;
        m->u.configure.kind = IT2N_CFG_BSPLINE;
        break;
    case 18:
        m->type = IT2N_MSG_GAP;
        m->u.gap.seq = 0x0103;
        m->u.gap.have = 0x0105;
        break;
    case 20: /* v1.2: misses 0x0103, has just kept 0x0106, holds 0x0104,
              * 0x0106 and 0x0110 */
        m->type = IT2N_MSG_GAP;
        m->u.gap.seq = 0x0103;
        m->u.gap.have = 0x0106;
        m->u.gap.held = 0x1005u;
        break;
    case 21: /* v1.2: ACK of 0x0102, naming 0x0101, 0x0100 and 0x00FE */
        m->type = IT2N_MSG_ACK;
        m->u.ack.seq = 0x0102;
        m->u.ack.acked = 0x000Bu;
        break;
    case 22: /* v1.2: 0x0104 delivered, its answer deferred */
        m->type = IT2N_MSG_RCVD;
        m->u.rcvd.seq = 0x0104;
        break;
    case 23: /* v1.3 in a v1.2 frame: PUT FINE, T, I, F in Q30 (0.9, 0.3
              * and 0.1 rounded to 2^-30: what 'it2n' reads, which Q24
              * would round); i = 200 beyond a Bezier degree */
        m->type = IT2N_MSG_PUT;
        m->u.put.model = 2;
        m->u.put.flags = IT2N_PUT_FINE;
        m->u.put.count = 2;
        m->u.put.e[0].i = 200;
        m->u.put.e[0].j = 1;
        m->u.put.e[0].fp = IT2N_FP_LL;
        m->u.put.e[0].vals[IT2N_CH_X] = -23 * IT2N_VAL_ONE;
        m->u.put.e[0].vals[IT2N_CH_Y] = IT2N_VAL_ONE;
        m->u.put.e[0].vals[IT2N_CH_T] = 966367642;
        m->u.put.e[0].vals[IT2N_CH_I] = 322122547;
        m->u.put.e[0].vals[IT2N_CH_F] = 107374182;
        m->u.put.e[1] = m->u.put.e[0];
        m->u.put.e[1].fp = IT2N_FP_RR;
        m->u.put.e[1].vals[IT2N_CH_X] = -11 * IT2N_VAL_ONE;
        m->u.put.e[1].vals[IT2N_CH_Y] = 13 * IT2N_VAL_ONE;
        m->u.put.e[1].vals[IT2N_CH_T] = (it2n_val)1 << 30; /* 1.0 */
        break;
    case 11:
        m->type = IT2N_MSG_ACK;
        m->u.ack.seq = 0x0102;
        break;
    case 12:
        m->type = IT2N_MSG_NACK;
        m->u.nack.seq = 0x0102;
        m->u.nack.code = IT2N_ERR_RANGE;
        m->u.nack.i = 1;
        m->u.nack.j = 2;
        m->u.nack.fp = IT2N_FP_D;
        m->u.nack.ch = IT2N_CH_T;
        m->u.nack.value = IT2N_VAL_ONE + 1;
        m->u.nack.lo = 0;
        m->u.nack.hi = IT2N_VAL_ONE;
        break;
    case 13:
        m->type = IT2N_MSG_QUERY_RESULT;
        m->u.query_result.re = 0x0104;
        m->u.query_result.model = 2;
        m->u.query_result.u = IT2N_WIRE_PAR_ONE / 2u;
        m->u.query_result.w = IT2N_WIRE_PAR_ONE;
        for (a = 0; a < IT2N_FP_COUNT; a++)
            vals(m->u.query_result.v[a], IT2N_CH_COUNT, 100u + 6u * a);
        /* bit fp*3+k: membership k of footprint fp outside [0, 1], as the
         * values say (the v1.0 vector had a bit its values contradicted) */
        for (a = 0; a < IT2N_FP_COUNT; a++)
            for (b = 0; b < 3u; b++) {
                it2n_val x = m->u.query_result.v[a][IT2N_CH_T + b];
                if (x < 0 || x > IT2N_VAL_ONE)
                    m->u.query_result.out_of_range |= 1u << (3u * a + b);
            }
        vals(m->u.query_result.sum.upper_min, 3, 200);
        vals(m->u.query_result.sum.upper_max, 3, 203);
        vals(m->u.query_result.sum.lower_min, 3, 206);
        vals(m->u.query_result.sum.lower_max, 3, 209);
        break;
    case 14:
        m->type = IT2N_MSG_LOCATE_RESULT;
        m->u.locate_result.re = 0x0105;
        m->u.locate_result.model = 2;
        m->u.locate_result.x = -17 * IT2N_VAL_ONE;
        m->u.locate_result.y = IT2N_VAL_ONE / 2;
        for (a = 0; a < IT2N_FP_COUNT; a++) {
            it2n_locate_wire *f = &m->u.locate_result.fp[a];
            f->u = (uint32_t)(a * 0x08000000u);
            f->w = IT2N_WIRE_PAR_ONE - f->u;
            f->status = (uint8_t)(a % 3u);
            f->residual = (it2n_val)a * 3;
            vals(f->v, IT2N_CH_COUNT, 300u + 6u * a);
        }
        break;
    case 15:
        m->type = IT2N_MSG_SAMPLE_DATA;
        m->u.sample_data.re = 0x0106;
        m->u.sample_data.model = 2;
        m->u.sample_data.fp = IT2N_FP_D;
        m->u.sample_data.rows = 11;
        m->u.sample_data.cols = 300;
        m->u.sample_data.start = 3297;
        m->u.sample_data.count = 3;
        for (a = 0; a < 3u; a++)
            vals(m->u.sample_data.v[a], IT2N_CH_COUNT, 400u + 6u * a);
        break;
    case 16:
        m->type = IT2N_MSG_NET_ROW;
        m->u.net_row.re = 0x0107;
        m->u.net_row.model = 2;
        m->u.net_row.fp = IT2N_FP_R;
        m->u.net_row.n = 3;
        m->u.net_row.m = 3;
        m->u.net_row.row = 1;
        for (b = 0; b < 4u; b++)
            vals(m->u.net_row.v[b], IT2N_CH_COUNT, 500u + 6u * b);
        break;
    default:
        m->type = IT2N_MSG_STATUS;
        m->u.status.re = 0x0108;
        m->u.status.model = 2;
        m->u.status.state = IT2N_MS_COLLECTING;
        m->u.status.n = 3;
        m->u.status.m = 3;
        m->u.status.flags = IT2N_F_CHORD;
        m->u.status.missing = 5;
        m->u.status.generation = 7;
        m->u.status.last_error = IT2N_ERR_DUPLICATE;
        break;
    }
}

const char *it2n_proto_vector(unsigned k, it2n_frame_hdr *hdr, it2n_msg *msg)
{
    static const char *const names[IT2N_VECTOR_COUNT] = {
        "hello",  "configure",         "put",           "commit",      "query",   "locate",
        "sample", "get_net",           "get_status",    "reset",       "event",   "ack",
        "nack",   "query_result",      "locate_result", "sample_data", "net_row", "status",
        "gap",    "configure_bspline", "gap_held",      "ack_acked",   "rcvd",    "put_fine"};

    if (k >= IT2N_VECTOR_COUNT)
        return NULL;
    memset(msg, 0, sizeof *msg);
    fill(k, msg);
    hdr->version = k >= IT2N_VECTOR_FIRST_V12 ? (uint8_t)IT2N_PROTO_VERSION_12 : (uint8_t)IT2N_PROTO_VERSION;
    hdr->type = msg->type;
    if (msg->type == IT2N_MSG_ACK || msg->type == IT2N_MSG_NACK || msg->type == IT2N_MSG_GAP ||
        msg->type == IT2N_MSG_RCVD) {
        hdr->flags = 0;
        hdr->seq = 0;
    } else {
        hdr->flags = (uint8_t)(IT2N_FLAG_REL | (k == 0u ? IT2N_FLAG_SYN : 0u));
        hdr->seq = (uint16_t)(0x0100u + k);
    }
    hdr->len = 0; /* set by whoever packs the payload */
    return names[k];
}
