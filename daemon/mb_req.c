/* mb_req.c — see mb_req.h. */
#include "mb_req.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "it2n_regmap.h"
#include "errs.h"
#include "log.h"
#include "loop.h"
#include "metrics.h"
#include "store.h"

int mb_req_session_init(struct mb_req_session *s, modbus_t *ctx, int is_tcp)
{
    memset(s, 0, sizeof *s);
    s->ctx = ctx;
    s->is_tcp = is_tcp;
    return 0;
}

void mb_req_session_free(struct mb_req_session *s)
{
    s->rsp_len = 0;
}

/* Eight registers (GCC/Clang vector extension: SSE2 on x86-64, plain
 * code elsewhere). */
typedef uint16_t mb_u16x8 __attribute__((vector_size(16)));

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define MB_SWAP_AVX2 1
/* x86-64 with AVX2 (checked at run time): regs[0..n) big-endian into dst,
 * sixteen registers per byte shuffle (VPSHUFB), then eight; returns how
 * many were done (a multiple of 8; the caller's loops do the rest). An FC 23
 * answer is 108 registers: 7 shuffles where the SSE2 shifts took 13 steps
 * of three operations (callgrind: about 160 -> 50 instructions). */
__attribute__((target("avx2"))) static unsigned swap16s_avx2(uint8_t *dst, const uint16_t *regs, unsigned n)
{
    const __m256i m = _mm256_setr_epi8(1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14, 1, 0, 3, 2, 5, 4, 7, 6, 9,
                                       8, 11, 10, 13, 12, 15, 14);
    unsigned i = 0;
    for (; i + 16u <= n; i += 16u)
        _mm256_storeu_si256((__m256i *)(void *)(dst + 2u * i),
                            _mm256_shuffle_epi8(_mm256_loadu_si256((const __m256i *)(const void *)(regs + i)), m));
    if (i + 8u <= n) {
        _mm_storeu_si128(
            (__m128i *)(void *)(dst + 2u * i),
            _mm_shuffle_epi8(_mm_loadu_si128((const __m128i *)(const void *)(regs + i)), _mm256_castsi256_si128(m)));
        i += 8u;
    }
    return i;
}
#endif

/* The reply to a request that succeeded, framed here into s->rsp as
 * libmodbus' modbus_reply() would frame it (the daemon owns its framing:
 * no scratch register mapping, no copy through it): TCP, the request's
 * transaction id, protocol 0, the length, the request's unit; RTU, the
 * slave address (the CRC is added when sent). FC 03/04/23 carry the
 * registers read (regs, n), FC 06 echoes the request, FC 16 echoes its
 * address and count. */
static void frame_reply(struct mb_req_session *s, const uint8_t *req, int fc, const uint16_t *regs, unsigned n)
{
    uint8_t *r = s->rsp;
    size_t hl = s->is_tcp ? 7u : 1u, k = hl;
    const uint8_t *pdu = req + hl;
    if (s->is_tcp) {
        r[0] = req[0];
        r[1] = req[1];
        r[2] = r[3] = 0;
        r[6] = req[6];
    } else {
        r[0] = req[0];
    }
    r[k++] = (uint8_t)fc;
    if (fc == MODBUS_FC_WRITE_SINGLE_REGISTER || fc == MODBUS_FC_WRITE_MULTIPLE_REGISTERS) {
        memcpy(r + k, pdu + 1, 4); /* address, value (06) or count (16) */
        k += 4;
    } else {
        r[k++] = (uint8_t)(n * 2u);
        unsigned i = 0;
#ifdef MB_SWAP_AVX2
        if (__builtin_cpu_supports("avx2"))
            i = swap16s_avx2(r + k, regs, n);
#endif
        /* Big-endian, eight registers per step (a byte swap in each 16-bit
         * lane of a 128-bit vector: three SSE2 instructions on x86-64),
         * then four (a 64-bit word): 108 registers are every FC 23 answer.
         * Little-endian hosts; elsewhere the loop below does it all. */
        for (; __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ && i + 8u <= n; i += 8u) {
            mb_u16x8 x;
            memcpy(&x, regs + i, sizeof x);
            x = (mb_u16x8)(x << 8 | x >> 8);
            memcpy(r + k + 2u * i, &x, sizeof x);
        }
        for (; __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ && i + 4u <= n; i += 4u) {
            uint64_t x;
            memcpy(&x, regs + i, sizeof x);
            x = (x & 0x00FF00FF00FF00FFu) << 8 | (x >> 8 & 0x00FF00FF00FF00FFu);
            memcpy(r + k + 2u * i, &x, sizeof x);
        }
        for (; i < n; i++) {
            r[k + 2u * i] = (uint8_t)(regs[i] >> 8);
            r[k + 2u * i + 1u] = (uint8_t)regs[i];
        }
        k += 2u * n;
    }
    if (s->is_tcp) {
        r[4] = (uint8_t)((k - 6u) >> 8);
        r[5] = (uint8_t)(k - 6u);
    }
    s->rsp_len = (int)k;
}

/* Send s->rsp: TCP, one send(); RTU through libmodbus (CRC, RS-485
 * direction control), no reply to a broadcast (as modbus_reply). A short
 * send is a failure, as in libmodbus. Returns 0 or -1. */
static int send_reply(struct mb_req_session *s)
{
    int len = s->rsp_len;
    s->rsp_len = 0;
    if (!s->is_tcp) {
        if (s->rsp[0] == MODBUS_BROADCAST_ADDRESS)
            return 0;
        return modbus_send_raw_request(s->ctx, s->rsp, len) < 0 ? -1 : 0;
    }
    /* Through the loop: with io_uring the send rides on the next wait. */
    return loop_send(modbus_get_socket(s->ctx), s->rsp, (size_t)len);
}

/* Answer req with exception `code`. libmodbus builds the reply function as
 * request function + 0x80 in a byte, so a request function >= 0x80 (no
 * Modbus function has the top bit) would come back as a normal-looking
 * reply (0x83 -> 03 01). Such a request is answered with its function
 * unchanged (top bit already set, so it reads as an exception) by handing
 * libmodbus a copy with bit 7 cleared; header and transaction id are the
 * request's. */
static int exception(struct mb_req_session *s, struct model *md, const uint8_t *req, int code)
{
    int hl = modbus_get_header_length(s->ctx);
    if (md)
        md->mb.exceptions++;
    metrics_modbus_reply(req[hl], code);
    if (s->is_tcp) {
        /* Framed here as modbus_reply_exception() frames it (MBAP with the
         * request's transaction and unit, length 3), and sent the way every
         * other TCP reply goes, in order with them. */
        memcpy(s->rsp, req, 4);
        s->rsp[4] = 0;
        s->rsp[5] = 3;
        s->rsp[6] = req[6];
        s->rsp[7] = (uint8_t)(req[hl] | 0x80u);
        s->rsp[8] = (uint8_t)code;
        s->rsp_len = 9;
        return send_reply(s);
    }
    if (req[hl] & 0x80u) {
        uint8_t copy[MODBUS_TCP_MAX_ADU_LENGTH > MODBUS_RTU_MAX_ADU_LENGTH ? MODBUS_TCP_MAX_ADU_LENGTH
                                                                           : MODBUS_RTU_MAX_ADU_LENGTH];
        memcpy(copy, req, (size_t)hl + 1u);
        copy[hl] = (uint8_t)(req[hl] & 0x7Fu);
        return modbus_reply_exception(s->ctx, copy, (unsigned)code) < 0 ? -1 : 0;
    }
    return modbus_reply_exception(s->ctx, req, (unsigned)code) < 0 ? -1 : 0;
}

/* A write request refused before it reached the map: last_error too. */
static int refuse_write(struct mb_req_session *s, struct model *md, const uint8_t *req, int code)
{
    mb_map_refused(md, code);
    return exception(s, md, req, code);
}

static unsigned u16at(const uint8_t *p)
{
    return (unsigned)p[0] << 8 | p[1];
}

/* A write request (06, 16, and 23 with its read half: rcount > 0) is all
 * or nothing (a models.c transaction: an undo log of what it changes, no
 * copy of the model). When it ends in an exception after something was changed
 * and journaled (FC 23 whose read half fails, e.g. results of a model the
 * write just reconfigured: 06; a configuration write whose CLEAR fails
 * after the new degrees were applied), the model, this connection's query
 * state and the WAL records queued since the start go back, and the
 * exception is answered at once: it means "nothing changed" (security
 * finding 8). A write refused before any change keeps its own report
 * (last_error). */
static int write_req(struct mb_req_session *s, struct model *md, const struct mb_map_opts *o,
                     const it2n_regmap_block *wb, unsigned waddr, unsigned wcount, const uint16_t *vals,
                     const it2n_regmap_block *rb, unsigned raddr, unsigned rcount, uint16_t *regs, int *persisted)
{
    int rc;
    *persisted = 0;
    if (!mb_map_block_changes_model(wb)) {
        /* Query registers: per connection, the model is not touched (no
         * transaction, no copy). write_query validates completely before
         * it changes s->q, so an exception leaves s->q as it was. The read
         * half reads like FC 04: the last durable state. */
        rc = mb_map_write_in(md, &s->q, o, wb, waddr, wcount, vals, persisted);
        if (rc == MB_MAP_OK && rcount > 0)
            rc = mb_map_read_in(models_view(md), &s->q, o, rb, raddr, rcount, regs);
        return rc;
    }
    struct mb_map_query q = s->q;
    struct model_txn t;
    models_txn_begin(&t);
    rc = mb_map_write_in(md, &s->q, o, wb, waddr, wcount, vals, persisted);
    /* The read half of FC 23: a write reads the model it just changed
     * (its reply waits for that change to be durable); a write that
     * changed nothing reads like FC 04, the last durable state. */
    if (rc == MB_MAP_OK && rcount > 0)
        rc = mb_map_read_in(*persisted ? md : models_view(md), &s->q, o, rb, raddr, rcount, regs);
    if (rc != MB_MAP_OK && *persisted) {
        it2n_errinfo why = md->last_err;
        models_txn_rollback(&t); /* the model and the WAL records queued since begin */
        md->last_err = why;
        if (rc == MB_MAP_BUSY && !why.code) /* the read half: results of a model no longer solved */
            mb_map_refused(md, rc);
        s->q = q;
        *persisted = 0;
    } else {
        models_txn_commit(&t);
    }
    return rc;
}

/* Access control: a write that would change the model (configuration or
 * upload block) through a read-only listener, or to a write-protected
 * unit, is refused with exception 02 (to this client the block is
 * read-only) before anything is looked at. The refusal is this client's
 * alone: the exception answers it, the model's last_error (read by every
 * client of the model) is left as it was. Query registers stay writable:
 * querying is reading. The first refusal per session is logged at notice
 * level, the rest at debug. */
static int write_denied(struct mb_req_session *s, int unit, const struct mb_map_opts *o, const it2n_regmap_block *b,
                        unsigned addr, unsigned count)
{
    int prot = (o->write_protect[unit / 8] >> (unit % 8)) & 1;
    if ((!s->read_only && !prot) || !mb_map_block_changes_model(b))
        return 0;
    int first = s->refused++ == 0;
    log_msg(first ? LOG_NOTICE : LOG_DEBUG, "%s: write to unit %d registers %u..%u refused: %s%s",
            s->who[0] ? s->who : "modbus", unit, addr, addr + count - 1,
            prot ? "unit is write-protected (write_protect)" : "read-only listener",
            first ? " (further refusals on this connection logged at debug level)" : "");
    return 1;
}

int mb_req_handle(struct mb_req_session *s, const uint8_t *req, int len, const struct mb_map_opts *o)
{
    int hl = modbus_get_header_length(s->ctx);
    int unit, fc, rc, persisted = 0;
    struct model *md;
    uint16_t vals[MODBUS_MAX_WR_WRITE_REGISTERS > MODBUS_MAX_WRITE_REGISTERS ? MODBUS_MAX_WR_WRITE_REGISTERS
                                                                             : MODBUS_MAX_WRITE_REGISTERS];
    uint16_t regs[MODBUS_MAX_READ_REGISTERS > MODBUS_MAX_WR_READ_REGISTERS ? MODBUS_MAX_READ_REGISTERS
                                                                           : MODBUS_MAX_WR_READ_REGISTERS];
    unsigned nregs = 0;
    const uint8_t *pdu = req + hl;
    int plen = len - hl - (s->is_tcp ? 0 : 2); /* RTU: CRC (already checked) */

    if (plen < 1)
        return 0;
    unit = req[hl - 1];
    fc = pdu[0];
    md = models_by_unit(unit);
    /* Modbus TCP addresses the server itself with unit 0xFF (and many
     * clients send 0): the default model answers ([modbus] default_model). */
    if (!md && s->is_tcp && (unit == 0 || unit == 0xFF) && o->default_unit > 0) {
        md = models_by_unit(o->default_unit);
        unit = o->default_unit; /* its write protection applies */
    }
    if (!md) {
        /* RTU: another slave on the bus (or broadcast) — stay silent. */
        if (!s->is_tcp)
            return 0;
        return exception(s, NULL, req, MB_MAP_GATEWAY_TARGET);
    }
    md->mb.requests++;
    switch (fc) {
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS: {
        if (plen != 5)
            return exception(s, md, req, MB_MAP_ILLEGAL_VALUE);
        unsigned addr = u16at(pdu + 1), count = u16at(pdu + 3);
        if (count < 1 || count > MODBUS_MAX_READ_REGISTERS)
            return exception(s, md, req, MB_MAP_ILLEGAL_VALUE);
        if (addr + count > IT2N_REGMAP_REG_MAP_END)
            return exception(s, md, req, MB_MAP_ILLEGAL_ADDRESS);
        /* Readers see the last durable state (models_view), never a
         * change whose batch is still being written. */
        rc = mb_map_read(models_view(md), &s->q, o, addr, count, regs);
        nregs = count;
        break;
    }
    case MODBUS_FC_WRITE_SINGLE_REGISTER: {
        if (plen != 5)
            return refuse_write(s, md, req, MB_MAP_ILLEGAL_VALUE);
        vals[0] = (uint16_t)u16at(pdu + 3);
        const it2n_regmap_block *wb = it2n_regmap_find(u16at(pdu + 1), 1);
        if (write_denied(s, unit, o, wb, u16at(pdu + 1), 1))
            return exception(s, md, req, MB_MAP_ILLEGAL_ADDRESS);
        rc = write_req(s, md, o, wb, u16at(pdu + 1), 1, vals, NULL, 0, 0, NULL, &persisted);
        break;
    }
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: {
        if (plen < 6)
            return refuse_write(s, md, req, MB_MAP_ILLEGAL_VALUE);
        unsigned addr = u16at(pdu + 1), count = u16at(pdu + 3), bytes = pdu[5];
        if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || bytes != count * 2 || plen != 6 + (int)bytes)
            return refuse_write(s, md, req, MB_MAP_ILLEGAL_VALUE);
        const it2n_regmap_block *wb = it2n_regmap_find(addr, count);
        if (write_denied(s, unit, o, wb, addr, count))
            return exception(s, md, req, MB_MAP_ILLEGAL_ADDRESS);
        for (unsigned k = 0; k < count; k++)
            vals[k] = (uint16_t)u16at(pdu + 6 + 2 * k);
        rc = write_req(s, md, o, wb, addr, count, vals, NULL, 0, 0, NULL, &persisted);
        break;
    }
    case MODBUS_FC_WRITE_AND_READ_REGISTERS: {
        if (plen < 10)
            return refuse_write(s, md, req, MB_MAP_ILLEGAL_VALUE);
        unsigned raddr = u16at(pdu + 1), rcount = u16at(pdu + 3);
        unsigned waddr = u16at(pdu + 5), wcount = u16at(pdu + 7), bytes = pdu[9];
        if (rcount < 1 || rcount > MODBUS_MAX_WR_READ_REGISTERS || wcount < 1 ||
            wcount > MODBUS_MAX_WR_WRITE_REGISTERS || bytes != wcount * 2 || plen != 10 + (int)bytes)
            return refuse_write(s, md, req, MB_MAP_ILLEGAL_VALUE);
        /* Check the read range before writing, so a bad read changes nothing. */
        const it2n_regmap_block *rb = it2n_regmap_find(raddr, rcount), *wb;
        if (!rb)
            return refuse_write(s, md, req, MB_MAP_ILLEGAL_ADDRESS);
        wb = it2n_regmap_find(waddr, wcount);
        if (write_denied(s, unit, o, wb, waddr, wcount))
            return exception(s, md, req, MB_MAP_ILLEGAL_ADDRESS);
        for (unsigned k = 0; k < wcount; k++)
            vals[k] = (uint16_t)u16at(pdu + 10 + 2 * k);
        rc = write_req(s, md, o, wb, waddr, wcount, vals, rb, raddr, rcount, regs, &persisted);
        /* As libmodbus' modbus_reply (which stored the written values
         * before reading): an overlapping read echoes what was written. */
        if (rc == MB_MAP_OK && waddr < raddr + rcount && raddr < waddr + wcount)
            for (unsigned k = 0; k < wcount; k++)
                if (waddr + k >= raddr && waddr + k < raddr + rcount)
                    regs[waddr + k - raddr] = vals[k];
        nregs = rcount;
        break;
    }
    default: return exception(s, md, req, MB_MAP_ILLEGAL_FUNCTION);
    }
    if (rc == MB_MAP_OK)
        frame_reply(s, req, fc, regs, nregs);
    if (persisted) {
        /* Held until the WAL commit (the reply framed now: the registers
         * read with the write). */
        memcpy(s->held, req, (size_t)len);
        s->held_len = len;
        s->held_exc = rc;
        s->held_model = md;
        s->held_batch = store_batch();
        return 1;
    }
    if (rc != MB_MAP_OK)
        return exception(s, md, req, rc);
    metrics_modbus_reply(fc, 0);
    return send_reply(s);
}

int mb_req_release(struct mb_req_session *s, int commit_ok)
{
    int len = s->held_len, exc = commit_ok ? s->held_exc : MB_MAP_DEVICE_FAILURE;
    s->held_len = 0;
    if (len <= 0)
        return 0;
    if (!commit_ok && s->held_model) {
        /* Not durable: refused with 04, and last_error says why, also for
         * a write that changed no model field the batch rollback marks
         * (e.g. the upload block): every refused write sets it. */
        struct model *md = s->held_model;
        memset(&md->last_err, 0, sizeof md->last_err);
        md->last_err.code = IT2ND_ERR_IO;
        md->last_err.i = md->last_err.j = -1;
        md->last_err.fp = md->last_err.ch = -1;
    }
    if (exc != MB_MAP_OK)
        return exception(s, s->held_model, s->held, exc);
    metrics_modbus_reply(s->held[modbus_get_header_length(s->ctx)], 0);
    return send_reply(s);
}
