/*
 * Message pack/unpack. One codec walks each layout for both directions, so
 * the writer and the reader cannot drift apart; validation then runs on the
 * struct with the same rules either way.
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include <string.h>

#include "it2n_msg.h"

typedef struct cur {
    uint8_t *out;      /* pack: destination                 */
    const uint8_t *in; /* unpack: source                    */
    size_t pos, end;   /* end: capacity (pack) / length     */
    bool pack;
    int err;
    it2n_proto_errinfo *info;
} cur;

static void fail(cur *c, int code, size_t off, int64_t value, int64_t limit)
{
    if (c->err != 0)
        return;
    c->err = code;
    if (c->info != NULL) {
        c->info->code = code;
        c->info->offset = (uint16_t)(off > 0xFFFFu ? 0xFFFFu : off);
        c->info->value = value;
        c->info->limit = limit;
    }
}

/* Move n bytes between the wire and tmp (little-endian order). */
static bool io(cur *c, uint8_t *tmp, size_t n)
{
    if (c->err != 0)
        return false;
    if (n > c->end - c->pos) {
        fail(c, c->pack ? IT2N_PROTO_ERR_NOSPACE : IT2N_PROTO_ERR_PAYLOAD, c->pos, (int64_t)c->end,
             (int64_t)(c->pos + n));
        return false;
    }
    if (c->pack)
        memcpy(c->out + c->pos, tmp, n);
    else
        memcpy(tmp, c->in + c->pos, n);
    c->pos += n;
    return true;
}

static void c_u8(cur *c, uint8_t *v)
{
    (void)io(c, v, 1u);
}

static void c_i8(cur *c, int8_t *v)
{
    uint8_t t = (uint8_t)*v;
    if (io(c, &t, 1u) && !c->pack)
        *v = (int8_t)(t >= 0x80u ? (int)t - 256 : (int)t);
}

static void c_u16(cur *c, uint16_t *v)
{
    uint8_t t[2];
    t[0] = (uint8_t)(*v & 0xFFu);
    t[1] = (uint8_t)(*v >> 8);
    if (io(c, t, 2u) && !c->pack)
        *v = (uint16_t)(t[0] | (t[1] << 8));
}

static void c_i16(cur *c, int16_t *v)
{
    uint16_t u = (uint16_t)*v;
    c_u16(c, &u);
    if (!c->pack && c->err == 0)
        *v = (int16_t)(u >= 0x8000u ? (int32_t)u - 65536 : (int32_t)u);
}

static void c_u32(cur *c, uint32_t *v)
{
    uint8_t t[4];
    unsigned k;
    for (k = 0; k < 4u; k++)
        t[k] = (uint8_t)((*v >> (8u * k)) & 0xFFu);
    if (io(c, t, 4u) && !c->pack) {
        *v = 0;
        for (k = 0; k < 4u; k++)
            *v |= (uint32_t)t[k] << (8u * k);
    }
}

static void c_u64(cur *c, uint64_t *v)
{
    uint8_t t[8];
    unsigned k;
    for (k = 0; k < 8u; k++)
        t[k] = (uint8_t)((*v >> (8u * k)) & 0xFFu);
    if (io(c, t, 8u) && !c->pack) {
        *v = 0;
        for (k = 0; k < 8u; k++)
            *v |= (uint64_t)t[k] << (8u * k);
    }
}

static void c_i64(cur *c, int64_t *v)
{
    uint64_t u = (uint64_t)*v;
    uint8_t t[8];
    unsigned k;
    for (k = 0; k < 8u; k++)
        t[k] = (uint8_t)((u >> (8u * k)) & 0xFFu);
    if (io(c, t, 8u) && !c->pack) {
        u = 0;
        for (k = 0; k < 8u; k++)
            u |= (uint64_t)t[k] << (8u * k);
        /* Two's complement without implementation-defined conversion. */
        *v = u >= 0x8000000000000000u ? -(int64_t)(~u) - 1 : (int64_t)u;
    }
}

static void c_vals(cur *c, it2n_val *v, size_t n)
{
    size_t k;
    for (k = 0; k < n && c->err == 0; k++)
        c_i64(c, &v[k]);
}

/* Field check: off is the payload offset the field was (or would be) at. */
static void need(cur *c, bool ok, size_t off, int64_t value, int64_t limit)
{
    if (!ok)
        fail(c, IT2N_PROTO_ERR_FIELD, off, value, limit);
}

/* Reserved byte: written 0 and required to be 0, so every message has one
 * encoding (a later use needs a new protocol version anyway). */
static void c_reserved(cur *c)
{
    size_t off = c->pos;
    uint8_t zero = 0;
    c_u8(c, &zero);
    need(c, c->err != 0 || zero == 0u, off, zero, 0);
}

static void c_fp(cur *c, uint8_t *fp)
{
    size_t off = c->pos;
    c_u8(c, fp);
    need(c, c->err != 0 || *fp < IT2N_FP_COUNT, off, *fp, IT2N_FP_COUNT - 1);
}

static void c_par(cur *c, uint32_t *p)
{
    size_t off = c->pos;
    c_u32(c, p);
    need(c, c->err != 0 || *p <= IT2N_WIRE_PAR_ONE, off, *p, IT2N_WIRE_PAR_ONE);
}

static void c_hello(cur *c, it2n_msg_hello *h)
{
    size_t off = c->pos;
    c_u8(c, &h->version_min);
    c_u8(c, &h->version_max);
    need(c, c->err != 0 || (h->version_min >= 1u && h->version_min <= h->version_max), off, h->version_min,
         h->version_max);
    c_u8(c, &h->max_degree);
    off = c->pos;
    c_u8(c, &h->window);
    need(c, c->err != 0 || h->window >= 1u, off, h->window, 1);
    c_u32(c, &h->caps);
    off = c->pos;
    c_u16(c, &h->max_payload);
    need(c, c->err != 0 || h->max_payload >= IT2N_HELLO_MIN_PAYLOAD, off, h->max_payload, IT2N_HELLO_MIN_PAYLOAD);
    c_u16(c, &h->max_models);
    (void)io(c, (uint8_t *)h->node, sizeof h->node);
}

static void c_configure(cur *c, it2n_msg_configure *m)
{
    size_t off = c->pos;
    unsigned max;
    c_u8(c, &m->model);
    c_u8(c, &m->n);
    c_u8(c, &m->m);
    c_u8(c, &m->flags);
    if (c->err != 0)
        return;
    /* v1.3: a fifth byte names the kind; its absence means Bezier (what
     * every v1.1 / v1.2 peer sends). Kind 0 has only the 4-byte form, so
     * every CONFIGURE has one encoding. */
    if (c->pack ? m->kind != IT2N_CFG_BEZIER : c->pos < c->end) {
        size_t ko = c->pos;
        c_u8(c, &m->kind);
        if (c->err != 0)
            return;
        need(c, m->model != IT2N_MODEL_ALL, off, m->model, IT2N_MODEL_ALL - 1);
        /* kind 0 after 4 bytes: a Bezier CONFIGURE one byte too long */
        if (m->kind == IT2N_CFG_BEZIER && !c->pack)
            fail(c, IT2N_PROTO_ERR_PAYLOAD, ko, (int64_t)c->end, 4);
        need(c, m->kind == IT2N_CFG_BSPLINE, ko, m->kind, IT2N_CFG_BSPLINE);
    } else {
        m->kind = IT2N_CFG_BEZIER;
        need(c, m->model != IT2N_MODEL_ALL, off, m->model, IT2N_MODEL_ALL - 1);
    }
    max = m->kind == IT2N_CFG_BSPLINE ? 255u : IT2N_MAX_DEGREE;
    need(c, m->n >= 1u && m->n <= max, off + 1u, m->n, max);
    need(c, m->m >= 1u && m->m <= max, off + 2u, m->m, max);
    need(c, (m->flags & ~IT2N_F_ALL) == 0u, off + 3u, m->flags, IT2N_F_ALL);
    /* the B-spline kind is uniform only: no chord-length parameters */
    need(c, m->kind != IT2N_CFG_BSPLINE || (m->flags & IT2N_F_CHORD) == 0u, off + 3u, m->flags,
         IT2N_F_ALL & ~IT2N_F_CHORD);
}

static void c_model(cur *c, uint8_t *model, bool all_ok)
{
    size_t off = c->pos;
    c_u8(c, model);
    need(c, c->err != 0 || all_ok || *model != IT2N_MODEL_ALL, off, *model, IT2N_MODEL_ALL - 1);
}

static void c_put(cur *c, it2n_msg_put *p)
{
    size_t off = c->pos, k;
    c_model(c, &p->model, false);
    c_u8(c, &p->flags);
    c_u8(c, &p->count);
    c_reserved(c);
    if (c->err != 0)
        return;
    /* v1.3: FINE (memberships in Q30); the server bounds them */
    need(c, (p->flags & ~IT2N_PUT_FLAGS) == 0u, off + 1u, p->flags, IT2N_PUT_FLAGS);
    need(c, p->count >= 1u && p->count <= IT2N_PUT_MAX, off + 2u, p->count, IT2N_PUT_MAX);
    for (k = 0; k < p->count && c->err == 0; k++) {
        it2n_put_entry *e = &p->e[k];
        /* i, j: any u8 since v1.3 (B-spline grids up to 256 x 256); the
         * server checks them against the model's n, m */
        c_u8(c, &e->i);
        c_u8(c, &e->j);
        c_fp(c, &e->fp);
        c_reserved(c);
        c_vals(c, e->vals, IT2N_CH_COUNT);
    }
}

static void c_event(cur *c, it2n_msg_event *e)
{
    size_t off;
    c_u8(c, &e->model);
    off = c->pos;
    c_u8(c, &e->kind);
    need(c, c->err != 0 || (e->kind >= IT2N_EV_CONFIGURED && e->kind <= IT2N_EV_LOST), off, e->kind, IT2N_EV_LOST);
    c_i16(c, &e->code);
    c_u32(c, &e->generation);
}

static void c_nack(cur *c, it2n_msg_nack *n)
{
    size_t off;
    c_u16(c, &n->seq);
    off = c->pos;
    c_i16(c, &n->code);
    need(c, c->err != 0 || n->code < 0, off, n->code, -1);
    c_i16(c, &n->i);
    c_i16(c, &n->j);
    c_i8(c, &n->fp);
    c_i8(c, &n->ch);
    c_i64(c, &n->value);
    c_i64(c, &n->lo);
    c_i64(c, &n->hi);
}

static void c_query_result(cur *c, it2n_msg_query_result *q)
{
    size_t k;
    c_u16(c, &q->re);
    c_model(c, &q->model, false);
    c_par(c, &q->u);
    c_par(c, &q->w);
    c_u32(c, &q->out_of_range);
    for (k = 0; k < IT2N_FP_COUNT; k++)
        c_vals(c, q->v[k], IT2N_CH_COUNT);
    c_vals(c, q->sum.upper_min, 3u);
    c_vals(c, q->sum.upper_max, 3u);
    c_vals(c, q->sum.lower_min, 3u);
    c_vals(c, q->sum.lower_max, 3u);
}

static void c_locate_result(cur *c, it2n_msg_locate_result *l)
{
    size_t k;
    c_u16(c, &l->re);
    c_model(c, &l->model, false);
    c_i64(c, &l->x);
    c_i64(c, &l->y);
    for (k = 0; k < IT2N_FP_COUNT && c->err == 0; k++) {
        it2n_locate_wire *f = &l->fp[k];
        size_t off;
        c_par(c, &f->u);
        c_par(c, &f->w);
        off = c->pos;
        c_u8(c, &f->status);
        need(c, c->err != 0 || f->status <= IT2N_LOC_NOCONV, off, f->status, IT2N_LOC_NOCONV);
        c_i64(c, &f->residual);
        c_vals(c, f->v, IT2N_CH_COUNT);
    }
}

static void c_sample_data(cur *c, it2n_msg_sample_data *s)
{
    size_t off, k;
    uint32_t total;
    c_u16(c, &s->re);
    c_model(c, &s->model, false);
    c_fp(c, &s->fp);
    off = c->pos;
    c_u16(c, &s->rows);
    c_u16(c, &s->cols);
    c_u32(c, &s->start);
    c_u8(c, &s->count);
    if (c->err != 0)
        return;
    total = (uint32_t)s->rows * s->cols;
    need(c, s->rows >= 2u, off, s->rows, 2);
    need(c, s->cols >= 2u, off + 2u, s->cols, 2);
    need(c, s->count >= 1u && s->count <= IT2N_SAMPLE_MAX, off + 8u, s->count, IT2N_SAMPLE_MAX);
    need(c, s->start < total && s->count <= total - s->start, off + 4u, s->start, total);
    for (k = 0; k < s->count && c->err == 0; k++)
        c_vals(c, s->v[k], IT2N_CH_COUNT);
}

static void c_net_row(cur *c, it2n_msg_net_row *r)
{
    size_t off, k;
    c_u16(c, &r->re);
    c_model(c, &r->model, false);
    c_fp(c, &r->fp);
    off = c->pos;
    c_u8(c, &r->n);
    c_u8(c, &r->m);
    c_u8(c, &r->row);
    if (c->err != 0)
        return;
    need(c, r->n >= 1u && r->n <= IT2N_MAX_DEGREE, off, r->n, IT2N_MAX_DEGREE);
    need(c, r->m >= 1u && r->m <= IT2N_MAX_DEGREE, off + 1u, r->m, IT2N_MAX_DEGREE);
    need(c, r->row <= r->n, off + 2u, r->row, r->n);
    for (k = 0; k <= r->m && c->err == 0; k++)
        c_vals(c, r->v[k], IT2N_CH_COUNT);
}

static void c_status(cur *c, it2n_msg_status *s)
{
    size_t off;
    c_u16(c, &s->re);
    c_model(c, &s->model, false);
    off = c->pos;
    c_u8(c, &s->state);
    need(c, c->err != 0 || s->state <= IT2N_MS_ERROR, off, s->state, IT2N_MS_ERROR);
    c_u8(c, &s->n);
    c_u8(c, &s->m);
    off = c->pos;
    c_u8(c, &s->flags);
    need(c, c->err != 0 || (s->flags & ~IT2N_F_ALL) == 0u, off, s->flags, IT2N_F_ALL);
    c_u16(c, &s->missing);
    c_u32(c, &s->generation);
    c_i16(c, &s->last_error);
}

/* Walk one message; the caller checks c->err and the final position. */
static void codec(cur *c, it2n_msg *m)
{
    switch (m->type) {
    case IT2N_MSG_HELLO: c_hello(c, &m->u.hello); break;
    case IT2N_MSG_CONFIGURE: c_configure(c, &m->u.configure); break;
    case IT2N_MSG_PUT: c_put(c, &m->u.put); break;
    case IT2N_MSG_COMMIT:
    case IT2N_MSG_GET_STATUS: c_model(c, &m->u.model.model, false); break;
    case IT2N_MSG_RESET: c_model(c, &m->u.model.model, true); break;
    case IT2N_MSG_QUERY:
        c_model(c, &m->u.query.model, false);
        c_par(c, &m->u.query.u);
        c_par(c, &m->u.query.w);
        break;
    case IT2N_MSG_LOCATE:
        c_model(c, &m->u.locate.model, false);
        c_i64(c, &m->u.locate.x);
        c_i64(c, &m->u.locate.y);
        break;
    case IT2N_MSG_SAMPLE: {
        size_t off;
        c_model(c, &m->u.sample.model, false);
        c_fp(c, &m->u.sample.fp);
        off = c->pos;
        c_u16(c, &m->u.sample.rows);
        c_u16(c, &m->u.sample.cols);
        need(c, c->err != 0 || m->u.sample.rows >= 2u, off, m->u.sample.rows, 2);
        need(c, c->err != 0 || m->u.sample.cols >= 2u, off + 2u, m->u.sample.cols, 2);
        break;
    }
    case IT2N_MSG_GET_NET:
        c_model(c, &m->u.get_net.model, false);
        c_fp(c, &m->u.get_net.fp);
        break;
    case IT2N_MSG_EVENT: c_event(c, &m->u.event); break;
    case IT2N_MSG_ACK:
        c_u16(c, &m->u.ack.seq);
        if (c->pack ? m->u.ack.acked != 0u : c->end == IT2N_ACK12_LEN) {
            c_u64(c, &m->u.ack.acked);
            /* one encoding: no earlier ACK is the 2-byte form */
            need(c, c->err != 0 || m->u.ack.acked != 0u, 2u, 0, 1);
        }
        break;
    case IT2N_MSG_RCVD: c_u16(c, &m->u.rcvd.seq); break;
    case IT2N_MSG_GAP:
        c_u16(c, &m->u.gap.seq);
        c_u16(c, &m->u.gap.have);
        /* v1.2 (12 bytes): the frames held beyond the gap. v1.1: 4 bytes,
         * packed so when held is 0. */
        if (c->pack ? m->u.gap.held != 0u : c->end == IT2N_GAP12_LEN) {
            c_u64(c, &m->u.gap.held);
            need(c, c->err != 0 || m->u.gap.held != 0u, 4u, 0, 1);
        }
        break;
    case IT2N_MSG_NACK: c_nack(c, &m->u.nack); break;
    case IT2N_MSG_QUERY_RESULT: c_query_result(c, &m->u.query_result); break;
    case IT2N_MSG_LOCATE_RESULT: c_locate_result(c, &m->u.locate_result); break;
    case IT2N_MSG_SAMPLE_DATA: c_sample_data(c, &m->u.sample_data); break;
    case IT2N_MSG_NET_ROW: c_net_row(c, &m->u.net_row); break;
    case IT2N_MSG_STATUS: c_status(c, &m->u.status); break;
    default: fail(c, IT2N_PROTO_ERR_TYPE, 0, m->type, 0); break;
    }
}

int it2n_msg_pack(const it2n_msg *msg, uint8_t *buf, size_t cap, it2n_proto_errinfo *err)
{
    cur c;

    memset(&c, 0, sizeof c);
    c.out = buf;
    c.end = cap > IT2N_PROTO_MAX_PAYLOAD ? IT2N_PROTO_MAX_PAYLOAD : cap;
    c.pack = true;
    c.info = err;
    /* The codec takes a mutable struct because unpacking writes into it; in
     * pack mode every c_* helper only reads, so msg is never modified (and a
     * copy would cost another 1 KiB of stack). */
    codec(&c, (it2n_msg *)(uintptr_t)msg);
    if (c.err != 0)
        return c.err;
    if (err != NULL)
        memset(err, 0, sizeof *err);
    return (int)c.pos;
}

/* The payload length a message of `type` must have, from its fixed size
 * or its count field (0 when the bytes at hand do not say). */
static size_t expected_len(uint8_t type, const uint8_t *p, size_t len)
{
    switch (type) {
    case IT2N_MSG_HELLO: return 28u;
    case IT2N_MSG_CONFIGURE: /* v1.3: 5 bytes when byte 4 names a kind */
        return len >= IT2N_CONFIGURE13_LEN && p[4] != IT2N_CFG_BEZIER ? IT2N_CONFIGURE13_LEN : 4u;
    case IT2N_MSG_PUT: return len >= 3u ? IT2N_PUT_HDR + IT2N_PUT_ENTRY * (size_t)p[2] : 0u;
    case IT2N_MSG_COMMIT:
    case IT2N_MSG_GET_STATUS:
    case IT2N_MSG_RESET: return 1u;
    case IT2N_MSG_QUERY: return 9u;
    case IT2N_MSG_LOCATE: return 17u;
    case IT2N_MSG_SAMPLE: return 6u;
    case IT2N_MSG_GET_NET: return 2u;
    case IT2N_MSG_EVENT: return 8u;
    case IT2N_MSG_ACK: return len == IT2N_ACK12_LEN ? IT2N_ACK12_LEN : 2u;
    case IT2N_MSG_GAP: return len == IT2N_GAP12_LEN ? IT2N_GAP12_LEN : 4u;
    case IT2N_MSG_RCVD: return 2u;
    case IT2N_MSG_NACK: return 34u;
    case IT2N_MSG_QUERY_RESULT: return 447u;
    case IT2N_MSG_LOCATE_RESULT: return 474u;
    case IT2N_MSG_SAMPLE_DATA: return len >= 13u ? IT2N_SAMPLE_HDR + IT2N_SAMPLE_POINT * (size_t)p[12] : 0u;
    case IT2N_MSG_NET_ROW: return len >= 6u ? IT2N_NET_ROW_HDR + IT2N_SAMPLE_POINT * ((size_t)p[5] + 1u) : 0u;
    case IT2N_MSG_STATUS: return 15u;
    default: return 0u;
    }
}

int it2n_msg_unpack(uint8_t type, const uint8_t *p, size_t len, it2n_msg *msg, it2n_proto_errinfo *err)
{
    cur c;

    memset(&c, 0, sizeof c);
    memset(msg, 0, sizeof *msg);
    msg->type = type;
    c.in = p;
    c.end = len;
    c.info = err;
    codec(&c, msg);
    if (c.err == 0 && c.pos != len)
        fail(&c, IT2N_PROTO_ERR_PAYLOAD, c.pos, (int64_t)len, (int64_t)c.pos);
    if (c.err == IT2N_PROTO_ERR_PAYLOAD && err != NULL) {
        /* value = length received, hi = the length the type requires */
        size_t want = expected_len(type, p, len);
        err->value = (int64_t)len;
        if (want != 0u)
            err->limit = (int64_t)want;
    }
    if (c.err != 0)
        return c.err;
    if (err != NULL)
        memset(err, 0, sizeof *err);
    return IT2N_OK;
}

uint32_t it2n_par_to_wire(it2n_par p)
{
    if (p <= 0)
        return 0u;
    if (p >= IT2N_PAR_ONE)
        return IT2N_WIRE_PAR_ONE;
    return (uint32_t)((p + 2) >> 2);
}

it2n_par it2n_par_from_wire(uint32_t w)
{
    return (it2n_par)w * 4;
}

const char *it2n_msg_name(uint8_t type)
{
    switch (type) {
    case IT2N_MSG_HELLO: return "HELLO";
    case IT2N_MSG_CONFIGURE: return "CONFIGURE";
    case IT2N_MSG_PUT: return "PUT";
    case IT2N_MSG_COMMIT: return "COMMIT";
    case IT2N_MSG_QUERY: return "QUERY";
    case IT2N_MSG_LOCATE: return "LOCATE";
    case IT2N_MSG_SAMPLE: return "SAMPLE";
    case IT2N_MSG_GET_NET: return "GET_NET";
    case IT2N_MSG_GET_STATUS: return "GET_STATUS";
    case IT2N_MSG_RESET: return "RESET";
    case IT2N_MSG_EVENT: return "EVENT";
    case IT2N_MSG_ACK: return "ACK";
    case IT2N_MSG_GAP: return "GAP";
    case IT2N_MSG_RCVD: return "RCVD";
    case IT2N_MSG_NACK: return "NACK";
    case IT2N_MSG_QUERY_RESULT: return "QUERY_RESULT";
    case IT2N_MSG_LOCATE_RESULT: return "LOCATE_RESULT";
    case IT2N_MSG_SAMPLE_DATA: return "SAMPLE_DATA";
    case IT2N_MSG_NET_ROW: return "NET_ROW";
    case IT2N_MSG_STATUS: return "STATUS";
    default: return NULL;
    }
}

const char *it2n_proto_strerror(int code)
{
    switch (code) {
    case IT2N_PROTO_ERR_COBS: return "bad byte stuffing or truncated frame";
    case IT2N_PROTO_ERR_SHORT: return "frame shorter than header and CRC";
    case IT2N_PROTO_ERR_CRC: return "CRC mismatch";
    case IT2N_PROTO_ERR_OVERSIZE: return "frame exceeds the maximum size";
    case IT2N_PROTO_ERR_LENGTH: return "header length disagrees with frame";
    case IT2N_PROTO_ERR_VERSION: return "unsupported protocol version";
    case IT2N_PROTO_ERR_TYPE: return "unknown message type";
    case IT2N_PROTO_ERR_PAYLOAD: return "payload size wrong for its type";
    case IT2N_PROTO_ERR_FIELD: return "field outside its range";
    case IT2N_PROTO_ERR_NOSYNC: return "receiver not synchronised";
    case IT2N_PROTO_ERR_BUSY: return "send window full";
    case IT2N_PROTO_ERR_TIMEOUT: return "no acknowledgement after retries";
    case IT2N_PROTO_ERR_STREAM: return "stream I/O error";
    case IT2N_PROTO_ERR_MODEL: return "unknown model id";
    case IT2N_PROTO_ERR_SEQ: return "sequence number not awaiting an ACK";
    case IT2N_PROTO_ERR_NOSPACE: return "too large for the buffer or the peer's max_payload";
    case IT2N_PROTO_ERR_DOWN: return "link declared down: frame dropped";
    case IT2N_PROTO_ERR_SESSION: return "session unknown to the peer: HELLO for a new one";
    default: return code >= IT2N_ERR_NOCONV && code <= 0 ? "core error" : "unknown error";
    }
}
