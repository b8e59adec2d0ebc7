/* spb_dcmd.c — see spb_dcmd.h. */
#include "spb_dcmd.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "log.h"
#include "spb_metrics.h"
#include "spb_payload.h"

struct dcmd {
    int id;
    int nm;
    const struct mb_map_opts *o;
    float q[2];
    int has_q[2];
    float xy[2];
    int has_xy[2];
    uint16_t page[3];
    int has_page[3];
    uint16_t up[IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I];
    unsigned upmask;
    int bad;
    char why[200];
};

static int dcmd_index(const struct dcmd *c, const struct spb_payload_in *m)
{
    char name[96], desc[200];
    const char *unit;
    if (m->name) {
        for (int k = 0; k < c->nm; k++) {
            spb_metrics_info(c->o, k, name, sizeof name, desc, sizeof desc, &unit);
            if (!strcmp(name, m->name))
                return k;
        }
        return -1;
    }
    if (m->has_alias && m->alias >= (uint64_t)(c->id + 1) * SPB_DEV_ALIAS &&
        m->alias < (uint64_t)(c->id + 1) * SPB_DEV_ALIAS + (uint64_t)c->nm)
        return (int)(m->alias - (uint64_t)(c->id + 1) * SPB_DEV_ALIAS);
    return -1;
}

/* The first reason is the one reported; what: the metric, or NULL. */
static void dcmd_refuse(struct dcmd *c, const char *what, const char *reason)
{
    if (!c->bad++)
        snprintf(c->why, sizeof c->why, "%s%s%s", what ? what : "", what ? ": " : "", reason);
}

static void dcmd_metric(void *ctx, const struct spb_payload_in *m)
{
    struct dcmd *c = ctx;
    char label[64];
    int idx = dcmd_index(c, m), rel = idx;
    if (m->name)
        snprintf(label, sizeof label, "%s", m->name);
    else
        snprintf(label, sizeof label, "alias %llu", (unsigned long long)m->alias);
    if (idx < 0) {
        dcmd_refuse(c, label, "no such metric on this device");
        return;
    }
    switch (spb_metrics_seg(&rel)) {
    case SPB_SEG_QIN:
        if (m->kind == SPB_PAYLOAD_IN_FLOAT)
            c->q[rel] = (float)m->d;
        else if (m->kind == SPB_PAYLOAD_IN_INT || m->kind == SPB_PAYLOAD_IN_LONG)
            c->q[rel] = (float)m->u;
        else {
            dcmd_refuse(c, label, "expected a Float");
            return;
        }
        c->has_q[rel] = 1;
        return;
    case SPB_SEG_QLOC:
        if (m->kind == SPB_PAYLOAD_IN_FLOAT)
            c->xy[rel] = (float)m->d;
        else if (m->kind == SPB_PAYLOAD_IN_INT)
            c->xy[rel] = (float)(int32_t)(uint32_t)m->u;
        else if (m->kind == SPB_PAYLOAD_IN_LONG)
            c->xy[rel] = (float)(int64_t)m->u;
        else {
            dcmd_refuse(c, label, "expected a Float");
            return;
        }
        c->has_xy[rel] = 1;
        return;
    case SPB_SEG_PAGE:
        if ((m->kind != SPB_PAYLOAD_IN_INT && m->kind != SPB_PAYLOAD_IN_LONG) || m->u > 65535) {
            dcmd_refuse(c, label, "expected an integer 0..65535");
            return;
        }
        c->page[rel] = (uint16_t)m->u;
        c->has_page[rel] = 1;
        return;
    case SPB_SEG_UPLOAD: {
        const it2n_regmap_field *f = spb_metrics_upload_field(rel);
        uint16_t *r = &c->up[f->addr - IT2N_REGMAP_REG_UP_I];
        int64_t v;
        if (m->kind == SPB_PAYLOAD_IN_INT)
            v = f->type == IT2N_REGMAP_TYPE_I32 ? (int64_t)(int32_t)(uint32_t)m->u : (int64_t)(uint32_t)m->u;
        else if (m->kind == SPB_PAYLOAD_IN_LONG)
            v = (int64_t)m->u;
        else if (m->kind == SPB_PAYLOAD_IN_FLOAT && m->d == (double)(int64_t)m->d)
            v = (int64_t)m->d;
        else {
            dcmd_refuse(c, label, "expected an integer (the register's value)");
            return;
        }
        if (f->type == IT2N_REGMAP_TYPE_I32 ? (v < INT32_MIN || v > INT32_MAX) : (v < 0 || v > 65535)) {
            dcmd_refuse(c, label, "out of the register's range");
            return;
        }
        if (f->type == IT2N_REGMAP_TYPE_I32) {
            r[0] = (uint16_t)((uint32_t)v >> 16);
            r[1] = (uint16_t)v;
        } else {
            r[0] = (uint16_t)v;
        }
        c->upmask |= 1u << rel;
        return;
    }
    default:
        dcmd_refuse(c, label,
                    "read-only (a DCMD may write Query/u, Query/w, Query/x, Query/y, Net/Page/fp, "
                    "Net/Page/ch, Net/Page/row and the Upload metrics)");
        return;
    }
}

void spb_dcmd_apply(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const uint8_t *buf,
                    size_t len)
{
    struct dcmd c;
    int rc, persisted, id = md->id;
    unsigned all = (1u << spb_metrics_upload_count()) - 1u;
    char why[128];
    memset(&c, 0, sizeof c);
    c.id = id;
    c.o = o;
    c.nm = spb_metrics_count(o);
    if (spb_payload_cmd_each(buf, len, dcmd_metric, &c, why, sizeof why)) {
        log_warn("sparkplug: DCMD model-%d refused: %s", id, why);
        mb_map_refused(md, MB_MAP_ILLEGAL_VALUE);
        return;
    }
    if (!c.bad && c.upmask && c.upmask != all)
        dcmd_refuse(&c, NULL,
                    "the 9 Upload metrics are one data point and go together (as one FC16 of registers "
                    "40..51)");
    if (!c.bad && (c.has_q[0] || c.has_q[1]) && (c.has_xy[0] || c.has_xy[1]))
        dcmd_refuse(&c, NULL, "a query is (u, w) or a locate (x, y), not both (as one Modbus write may not mix them)");
    if (!c.bad && c.upmask && ((o->write_protect[md->unit / 8] >> (md->unit % 8)) & 1))
        dcmd_refuse(&c, NULL, "the model is write-protected ([model:] write_protect)");
    if (c.bad) {
        /* Nothing changes; the refusal is the report, as for Modbus. */
        log_warn("sparkplug: DCMD model-%d refused: %s", id, c.why);
        mb_map_refused(md, MB_MAP_ILLEGAL_VALUE);
        return;
    }
    if (c.has_q[0] || c.has_q[1]) {
        uint16_t regs[4];
        float cur[2] = {0.0f, 0.0f};
        if (q->kind == 1 && mb_map_read(md, q, o, IT2N_REGMAP_REG_Q_UF, 4, regs) == MB_MAP_OK) {
            cur[0] = it2n_regmap_get_f32(&regs[0], IT2N_REGMAP_WO_ABCD);
            cur[1] = it2n_regmap_get_f32(&regs[2], IT2N_REGMAP_WO_ABCD);
        }
        it2n_regmap_put_f32(&regs[0], c.has_q[0] ? c.q[0] : cur[0], IT2N_REGMAP_WO_ABCD);
        it2n_regmap_put_f32(&regs[2], c.has_q[1] ? c.q[1] : cur[1], IT2N_REGMAP_WO_ABCD);
        rc = mb_map_write(md, q, o, IT2N_REGMAP_REG_Q_UF, 4, regs, &persisted);
        if (rc != MB_MAP_OK)
            log_warn("sparkplug: DCMD model-%d: query refused (u, w in [0, 1]): exception %02X", id, (unsigned)rc);
    }
    if (c.has_xy[0] || c.has_xy[1]) {
        /* A locate, as a Modbus write of q_x_f and q_y_f: an axis not
         * given keeps the value in use (0 before any locate). */
        uint16_t regs[4];
        float cur[2] = {0.0f, 0.0f};
        if (q->kind == 2 && mb_map_read(md, q, o, IT2N_REGMAP_REG_Q_XF, 4, regs) == MB_MAP_OK) {
            cur[0] = it2n_regmap_get_f32(&regs[0], IT2N_REGMAP_WO_ABCD);
            cur[1] = it2n_regmap_get_f32(&regs[2], IT2N_REGMAP_WO_ABCD);
        }
        it2n_regmap_put_f32(&regs[0], c.has_xy[0] ? c.xy[0] : cur[0], IT2N_REGMAP_WO_ABCD);
        it2n_regmap_put_f32(&regs[2], c.has_xy[1] ? c.xy[1] : cur[1], IT2N_REGMAP_WO_ABCD);
        rc = mb_map_write(md, q, o, IT2N_REGMAP_REG_Q_XF, 4, regs, &persisted);
        if (rc != MB_MAP_OK)
            log_warn("sparkplug: DCMD model-%d: locate refused (x, y finite): exception %02X", id, (unsigned)rc);
    }
    if (c.has_page[0] || c.has_page[1] || c.has_page[2]) {
        /* The page select, as a Modbus write of registers 96..98. */
        uint16_t regs[3];
        if (mb_map_read(md, q, o, IT2N_REGMAP_REG_PG_FP, 3, regs) == MB_MAP_OK) {
            for (int k = 0; k < 3; k++)
                if (c.has_page[k])
                    regs[k] = c.page[k];
            rc = mb_map_write(md, q, o, IT2N_REGMAP_REG_PG_FP, 3, regs, &persisted);
            if (rc != MB_MAP_OK)
                log_warn("sparkplug: DCMD model-%d: page select refused (fp 0..6, ch 0..5, row 0..257): exception %02X",
                         id, (unsigned)rc);
        }
    }
    if (c.upmask) {
        /* A data point: validated, journaled and made durable like a
         * Modbus upload (its DDATA follows the commit, on_model_changed). */
        struct model_txn t;
        models_txn_begin(&t);
        rc = mb_map_write(md, q, o, IT2N_REGMAP_REG_UP_I, IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I, c.up,
                          &persisted);
        if (rc != MB_MAP_OK && persisted) {
            it2n_errinfo e = md->last_err;
            models_txn_rollback(&t);
            md->last_err = e;
        } else {
            models_txn_commit(&t);
        }
        if (rc != MB_MAP_OK)
            log_warn("sparkplug: DCMD model-%d: data point refused: exception %02X, last_error %d", id, (unsigned)rc,
                     md->last_err.code);
    }
}
