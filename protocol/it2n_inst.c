/*
 * Instrument API over the reliable link (see it2n_inst.h).
 *
 * Copyright (c) 2026 the it2n authors. MIT licence (see LICENSE).
 */
#include <string.h>

#include "it2n_inst.h"

#define DEF_RTO 200u
#define DEF_TRIES 20u
#define DEF_TIMEOUT 10000u

static uint32_t now(const it2n_inst *c)
{
    return c->cfg.now_ms(c->cfg.user);
}

static int os_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    it2n_inst *c = (it2n_inst *)s->state;
    return c->cfg.write(c->cfg.user, buf, len) < 0 ? -1 : 0;
}

static int on_rx(void *app, uint16_t seq, const it2n_msg *m)
{
    it2n_inst *c = (it2n_inst *)app;
    (void)seq;
    if (m->type == IT2N_MSG_HELLO) {
        /* the daemon's limits bind what we send */
        c->hello = m->u.hello;
        c->peer_hello = 1;
        it2n_link_set_peer(&c->link, m->u.hello.window, m->u.hello.max_payload);
    } else if (m->type == IT2N_MSG_QUERY_RESULT && c->q_seq >= 0 && m->u.query_result.re == (uint16_t)c->q_seq) {
        if (c->q_out != NULL)
            *c->q_out = m->u.query_result;
        c->q_have = 1;
        c->q_seq = -1;
    }
    return 0; /* EVENTs and the rest: ACK */
}

static void on_done(void *app, uint16_t seq, uint8_t type, int code, const it2n_msg_nack *nack)
{
    it2n_inst *c = (it2n_inst *)app;
    if ((int32_t)seq == c->barrier)
        c->barrier = -1; /* answered (or given up): the barrier lifts */
    if (code == 0)
        return;
    if (type == IT2N_MSG_QUERY && c->q_seq == (int32_t)seq && code != IT2N_PROTO_ERR_TIMEOUT &&
        code != IT2N_PROTO_ERR_DOWN) {
        /* a refused QUERY changes nothing: its code, not a failure */
        c->q_seq = -1;
        c->q_code = code;
        return;
    }
    if (c->err != 0)
        return;
    c->err = code;
    c->err_seq = seq;
    c->err_type = type;
    if (nack != NULL)
        c->nack = *nack;
    else
        memset(&c->nack, 0, sizeof c->nack);
}

int it2n_inst_feed(it2n_inst *ctx, const uint8_t *data, size_t len)
{
    return it2n_link_input(&ctx->link, data, len, now(ctx));
}

int it2n_inst_poll(it2n_inst *ctx)
{
    if (ctx->cfg.read != NULL) {
        uint8_t buf[64];
        unsigned k;
        /* bounded: two maximal frames per call */
        for (k = 0; k < 2u * IT2N_FRAME_MAX_WIRE / sizeof buf + 1u; k++) {
            int n = ctx->cfg.read(ctx->cfg.user, buf, sizeof buf);
            if (n <= 0)
                break;
            (void)it2n_link_input(&ctx->link, buf, (size_t)n > sizeof buf ? sizeof buf : (size_t)n, now(ctx));
        }
    }
    (void)it2n_link_poll(&ctx->link, now(ctx));
    return ctx->err;
}

/* Read mode: poll until cond(ctx) holds, a failure, or the timeout. */
static int wait_for(it2n_inst *ctx, bool (*cond)(const it2n_inst *))
{
    uint32_t t0 = now(ctx);
    while (!cond(ctx)) {
        if (it2n_inst_poll(ctx) != 0)
            return ctx->err;
        if (cond(ctx))
            break;
        if (now(ctx) - t0 >= ctx->cfg.timeout_ms)
            return IT2N_PROTO_ERR_TIMEOUT;
        if (ctx->cfg.idle != NULL)
            ctx->cfg.idle(ctx->cfg.user);
    }
    return ctx->err;
}

/* CONFIGURE is a barrier (docs/protocol.md 4.2 rule 7): nothing goes out
 * while one is unanswered, and it goes out with nothing else in flight. */
static bool can_send(const it2n_inst *ctx)
{
    return ctx->barrier < 0 && it2n_link_can_send(&ctx->link);
}

static bool can_send_alone(const it2n_inst *ctx)
{
    return ctx->barrier < 0 && it2n_link_pending(&ctx->link) == 0u;
}

static bool all_answered(const it2n_inst *ctx)
{
    return it2n_link_pending(&ctx->link) == 0u;
}

static bool query_answered(const it2n_inst *ctx)
{
    return ctx->q_seq < 0;
}

/* Send m: waits for window room in read mode. seq or an error. */
static int32_t send(it2n_inst *ctx, const it2n_msg *m)
{
    bool (*ready)(const it2n_inst *) = m->type == IT2N_MSG_CONFIGURE ? can_send_alone : can_send;
    int32_t seq;
    if (ctx->err != 0)
        return ctx->err;
    /* HELLO opens the session (v1.2: before any other frame may go) */
    if (m->type != IT2N_MSG_HELLO && !ready(ctx)) {
        int r;
        if (ctx->cfg.read == NULL)
            return IT2N_PROTO_ERR_BUSY;
        r = wait_for(ctx, ready);
        if (r != 0)
            return r;
    }
    seq = it2n_link_send(&ctx->link, m, now(ctx));
    if (seq >= 0 && m->type == IT2N_MSG_CONFIGURE)
        ctx->barrier = seq;
    return seq;
}

/* ctx->msg is free once the batch is flushed: the scratch message for
 * everything else (no 1 KiB it2n_msg on the stack). */
static it2n_msg *scratch(it2n_inst *ctx, uint8_t type)
{
    memset(&ctx->msg, 0, sizeof ctx->msg);
    ctx->msg.type = type;
    return &ctx->msg;
}

/* Send the scratch message; it is free again afterwards. */
static int32_t send_scratch(it2n_inst *ctx)
{
    int32_t r = send(ctx, &ctx->msg);
    ctx->msg.type = 0;
    return r;
}

static void hello(it2n_inst *ctx, it2n_msg *m)
{
    size_t k;
    memset(m, 0, sizeof *m);
    m->type = IT2N_MSG_HELLO;
    /* the one version this context speaks */
    m->u.hello.version_min =
        ctx->cfg.version == IT2N_PROTO_VERSION ? (uint8_t)IT2N_PROTO_VERSION : (uint8_t)IT2N_PROTO_VERSION_12;
    m->u.hello.version_max = m->u.hello.version_min;
    m->u.hello.max_degree = IT2N_MAX_DEGREE;
    m->u.hello.window = it2n_link_window(&ctx->link);
    m->u.hello.caps = IT2N_CAP_INSTRUMENT | IT2N_CAP_Z | IT2N_CAP_CHORD | IT2N_CAP_TYPE1 | IT2N_CAP_BSPLINE;
    m->u.hello.max_payload = IT2N_PROTO_MAX_PAYLOAD;
    m->u.hello.max_models = 1;
    for (k = 0; ctx->cfg.node != NULL && k < sizeof m->u.hello.node && ctx->cfg.node[k] != '\0'; k++)
        m->u.hello.node[k] = ctx->cfg.node[k];
}

static int start(it2n_inst *ctx, uint16_t first_seq)
{
    it2n_link_cfg lc;
    int32_t r;
    memset(&lc, 0, sizeof lc);
    ctx->os.write = os_write;
    ctx->os.state = ctx;
    lc.out = &ctx->os;
    lc.on_rx = on_rx;
    lc.on_done = on_done;
    lc.app = ctx;
    lc.rto_ms = ctx->cfg.rto_ms;
    lc.max_tries = ctx->cfg.max_tries;
    lc.first_seq = first_seq;
    lc.session = ctx->cfg.session_id;
    /* v1.2 by default: the daemon hands out the session id */
    lc.version = ctx->cfg.version == IT2N_PROTO_VERSION ? (uint8_t)IT2N_PROTO_VERSION : (uint8_t)IT2N_PROTO_VERSION_12;
    r = it2n_link_init(&ctx->link, &lc);
    if (r != IT2N_OK)
        return (int)r;
    ctx->err = 0;
    ctx->peer_hello = 0;
    ctx->q_seq = -1;
    ctx->barrier = -1;
    ctx->q_have = 0;
    hello(ctx, &ctx->msg);
    r = send_scratch(ctx);
    if (r < 0)
        return (int)r;
    if (ctx->cfg.read != NULL)
        return wait_for(ctx, all_answered);
    return IT2N_OK;
}

int it2n_inst_open(it2n_inst *ctx, const it2n_inst_cfg *cfg)
{
    if (cfg == NULL || cfg->write == NULL || cfg->now_ms == NULL ||
        (cfg->version != 0u && cfg->version != IT2N_PROTO_VERSION && cfg->version != IT2N_PROTO_VERSION_12))
        return IT2N_ERR_INVAL;
    memset(ctx, 0, sizeof *ctx);
    ctx->cfg = *cfg;
    if (ctx->cfg.rto_ms == 0u)
        ctx->cfg.rto_ms = DEF_RTO;
    if (ctx->cfg.max_tries == 0u)
        ctx->cfg.max_tries = DEF_TRIES;
    if (ctx->cfg.timeout_ms == 0u)
        ctx->cfg.timeout_ms = DEF_TIMEOUT;
    return start(ctx, cfg->first_seq);
}

int it2n_inst_resync(it2n_inst *ctx, uint16_t first_seq)
{
    (void)it2n_link_drop_tx(&ctx->link);
    ctx->err = 0;
    return start(ctx, first_seq);
}

int it2n_inst_flush(it2n_inst *ctx)
{
    int32_t r;
    if (ctx->msg.type != IT2N_MSG_PUT || ctx->msg.u.put.count == 0u)
        return ctx->err;
    r = send(ctx, &ctx->msg);
    if (r < 0)
        return (int)r;
    ctx->puts++;
    ctx->entries += ctx->msg.u.put.count;
    ctx->msg.type = 0;
    return IT2N_OK;
}

/* Entries per PUT the daemon accepts (its max_payload). */
static unsigned put_max(const it2n_inst *ctx)
{
    unsigned k = (it2n_link_max_payload(&ctx->link) - IT2N_PUT_HDR) / IT2N_PUT_ENTRY;
    return k < IT2N_PUT_MAX ? k : IT2N_PUT_MAX;
}

/* Take one entry into the PUT batch of layout `flags` (0 or
 * IT2N_PUT_FINE); a batch of another model or layout, or a full one, is
 * sent first. */
static int put_entry(it2n_inst *ctx, uint8_t model, uint8_t flags, uint8_t i, uint8_t j, uint8_t fp,
                     const it2n_val vals[IT2N_CH_COUNT])
{
    it2n_put_entry *e;
    unsigned ch;
    int r;
    if (ctx->msg.type == IT2N_MSG_PUT &&
        (ctx->msg.u.put.model != model || ctx->msg.u.put.flags != flags || ctx->msg.u.put.count >= put_max(ctx))) {
        r = it2n_inst_flush(ctx); /* full, another model or layout: send it */
        if (r != 0)
            return r;
    }
    if (ctx->msg.type != IT2N_MSG_PUT) {
        memset(&ctx->msg, 0, sizeof ctx->msg);
        ctx->msg.type = IT2N_MSG_PUT;
        ctx->msg.u.put.model = model;
        ctx->msg.u.put.flags = flags;
    }
    e = &ctx->msg.u.put.e[ctx->msg.u.put.count++];
    e->i = i;
    e->j = j;
    e->fp = fp;
    for (ch = 0; ch < IT2N_CH_COUNT; ch++)
        e->vals[ch] = vals[ch];
    return IT2N_OK;
}

int it2n_inst_put(it2n_inst *ctx, uint8_t model, uint8_t i, uint8_t j, uint8_t fp, const it2n_val vals[IT2N_CH_COUNT])
{
    if (ctx->err != 0)
        return ctx->err;
    /* i, j: any u8 (v1.3: B-spline grids); the daemon bounds them by n, m */
    if (fp >= IT2N_FP_COUNT || model == IT2N_MODEL_ALL)
        return IT2N_PROTO_ERR_FIELD;
    return put_entry(ctx, model, 0u, i, j, fp, vals);
}

int it2n_inst_put_fine(it2n_inst *ctx, uint8_t model, uint8_t i, uint8_t j, uint8_t fp,
                       const it2n_val vals[IT2N_CH_COUNT])
{
    it2n_val q24[IT2N_CH_COUNT];
    unsigned ch;
    const unsigned shift = IT2N_MEMB_FRAC - IT2N_VAL_FRAC;
    if (ctx->err != 0)
        return ctx->err;
    if (fp >= IT2N_FP_COUNT || model == IT2N_MODEL_ALL)
        return IT2N_PROTO_ERR_FIELD;
    if (ctx->peer_hello && (ctx->hello.caps & IT2N_CAP_FINE) != 0u)
        return put_entry(ctx, model, IT2N_PUT_FINE, i, j, fp, vals);
    /* A daemon without FINE (v1.2, or whose HELLO has not arrived) reads
     * Q24 memberships only: sent so when that is exact (the same model),
     * refused otherwise, nothing taken (docs/protocol.md 5.4). */
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        if (ch >= IT2N_CH_T && ((uint64_t)vals[ch] & (((uint64_t)1 << shift) - 1u)) != 0u)
            return IT2N_PROTO_ERR_VERSION;
        q24[ch] = ch >= IT2N_CH_T ? vals[ch] / ((it2n_val)1 << shift) : vals[ch];
    }
    return put_entry(ctx, model, 0u, i, j, fp, q24);
}

int it2n_inst_configure(it2n_inst *ctx, uint8_t model, uint8_t n, uint8_t m, uint8_t flags)
{
    it2n_msg *c;
    int32_t r = it2n_inst_flush(ctx);
    if (r != 0)
        return (int)r;
    c = scratch(ctx, IT2N_MSG_CONFIGURE);
    c->u.configure.model = model;
    c->u.configure.n = n;
    c->u.configure.m = m;
    c->u.configure.flags = flags;
    r = send_scratch(ctx);
    return r < 0 ? (int)r : IT2N_OK;
}

int it2n_inst_configure_bspline(it2n_inst *ctx, uint8_t model, uint8_t n, uint8_t m, uint8_t flags)
{
    it2n_msg *c;
    int32_t r;
    if (ctx->err != 0)
        return ctx->err;
    /* a v1.2 daemon would NACK the 5-byte form as malformed: say why here */
    if (ctx->peer_hello && (ctx->hello.caps & IT2N_CAP_BSPLINE) == 0u)
        return IT2N_PROTO_ERR_VERSION;
    r = it2n_inst_flush(ctx);
    if (r != 0)
        return (int)r;
    c = scratch(ctx, IT2N_MSG_CONFIGURE);
    c->u.configure.model = model;
    c->u.configure.n = n;
    c->u.configure.m = m;
    c->u.configure.flags = flags;
    c->u.configure.kind = IT2N_CFG_BSPLINE;
    r = send_scratch(ctx); /* a field error: nothing sent (the link packs) */
    return r < 0 ? (int)r : IT2N_OK;
}

int it2n_inst_commit(it2n_inst *ctx, uint8_t model)
{
    it2n_msg *c;
    int32_t r = it2n_inst_flush(ctx);
    if (r != 0)
        return (int)r;
    c = scratch(ctx, IT2N_MSG_COMMIT);
    c->u.model.model = model;
    r = send_scratch(ctx);
    return r < 0 ? (int)r : IT2N_OK;
}

int it2n_inst_sync(it2n_inst *ctx)
{
    int r = it2n_inst_flush(ctx);
    if (r != 0)
        return r;
    if (ctx->cfg.read == NULL)
        return ctx->err != 0 ? ctx->err : all_answered(ctx) ? IT2N_OK : IT2N_PROTO_ERR_BUSY;
    return wait_for(ctx, all_answered);
}

int it2n_inst_query(it2n_inst *ctx, uint8_t model, uint32_t u, uint32_t w, it2n_msg_query_result *out)
{
    it2n_msg *q;
    int32_t seq;
    int r = it2n_inst_flush(ctx);
    if (r != 0)
        return r;
    q = scratch(ctx, IT2N_MSG_QUERY);
    q->u.query.model = model;
    q->u.query.u = u;
    q->u.query.w = w;
    seq = send_scratch(ctx);
    if (seq < 0)
        return (int)seq;
    ctx->q_seq = seq;
    ctx->q_have = 0;
    ctx->q_code = 0;
    ctx->q_out = out;
    if (ctx->cfg.read == NULL)
        return IT2N_OK;
    r = wait_for(ctx, query_answered);
    if (r != 0)
        return r;
    if (ctx->q_code != 0)
        return ctx->q_code;
    return ctx->q_have ? IT2N_OK : IT2N_PROTO_ERR_TIMEOUT;
}

bool it2n_inst_query_done(const it2n_inst *ctx)
{
    return ctx->q_have != 0u;
}

int it2n_inst_error(const it2n_inst *ctx, it2n_msg_nack *nack)
{
    if (nack != NULL)
        *nack = ctx->nack;
    return ctx->err;
}
