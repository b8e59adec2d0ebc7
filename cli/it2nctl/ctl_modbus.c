/*
 * it2nctl over Modbus TCP or RTU (libmodbus), following docs/registers.md:
 * status block, configuration + upload + commit for push, FC 23 queries
 * (write u, w or x, y and read the results in one transaction), the
 * control-net block. Values travel as the map carries them: parameters and
 * locations as scaled integers when that is exact, else float32; results
 * as float32 (memberships in [-1, 1] round-trip exactly, coordinates keep
 * 24 significant bits).
 */
#include "ctl.h"

#include "it2n_regmap.h"

#include <errno.h>
#include <math.h>
#include <netdb.h>
#include <sys/socket.h>
#include <modbus.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct mb_conn {
    modbus_t *ctx;
    char where[160]; /* "127.0.0.1:1502 unit 1" for messages */
    int word_order;  /* IT2N_REGMAP_WO_*, float32 registers          */
    int int32_order; /* IT2N_REGMAP_WO_*, u32/i32 registers (reg 27) */
    int coord_scale;
    bool have_map; /* word order / scale read              */
} mb_conn;

static const char *exc_text(int err)
{
    switch (err) {
    case EMBXILFUN: return "exception 01: function not supported";
    case EMBXILADD:
        return "exception 02: address refused (read-only listener, write-protected model, or not in the map)";
    case EMBXILVAL: return "exception 03: value refused";
    case EMBXSFAIL: return "exception 04: the solve failed";
    case EMBXSBUSY: return "exception 06: model incomplete or not solved";
    case EMBXGTAR: return "exception 0B: no model on this unit id";
    default: return NULL;
    }
}

/* Report a failed libmodbus call; returns the exit status. */
static int mb_fail(const mb_conn *c, const char *what)
{
    int e = errno;
    const char *x = exc_text(e);
    if (x != NULL) {
        fprintf(stderr, "it2nctl: %s: %s: %s\n", c->where, what, x);
        return CTL_EXIT_DATA;
    }
    fprintf(stderr, "it2nctl: %s: %s: %s\n", c->where, what,
            e == ETIMEDOUT ? "no answer (timeout)" : modbus_strerror(e));
    return CTL_EXIT_COMM;
}

static int rd(mb_conn *c, unsigned addr, unsigned count, uint16_t *out, const char *what)
{
    if (modbus_read_registers(c->ctx, (int)addr, (int)count, out) != (int)count) {
        return mb_fail(c, what);
    }
    return CTL_EXIT_OK;
}

static int wr(mb_conn *c, unsigned addr, unsigned count, const uint16_t *v, const char *what)
{
    if (modbus_write_registers(c->ctx, (int)addr, (int)count, v) != (int)count) {
        return mb_fail(c, what);
    }
    return CTL_EXIT_OK;
}

/* A float32 result back to Q24 (exact: a float has at most 24 significant
 * bits, and |value| < 2^39 for anything the core produces). */
static it2n_val f2q(float f)
{
    double d = (double)f * (double)IT2N_VAL_ONE;
    if (!(d > -9.0e18 && d < 9.0e18)) { /* NaN, inf: not from it2nd */
        return d < 0 ? INT64_MIN >> 1 : INT64_MAX >> 1;
    }
    return (it2n_val)llround(d);
}

/* v as the scaled integer register value the daemon reads back to exactly
 * v (register = value * scale, i32); false when there is none. */
static bool exact_scaled(it2n_val v, int64_t scale, int64_t *out)
{
    int sat = 0;
    int64_t k = it2n_regmap_q24_to_scaled(v, (int32_t)scale, INT32_MIN, INT32_MAX, &sat);
    if (sat || it2n_regmap_q24_from_scaled(k, (int32_t)scale) != v) {
        return false;
    }
    *out = k;
    return true;
}

/* A Q30 membership (how the CSV reader stores it) to the nearest scaled
 * integer, and whether that is exact: the daemon's Q24 value of the
 * register is then the Q24 rounding of the decimal itself (rounding the
 * Q30 value to Q24 first could move a tie by one LSB and refuse a 4-decimal
 * membership). */
__extension__ typedef __int128 i128; /* host tool: |q30 * scale| needs 62 bits plus rounding */

static int64_t memb_scaled(it2n_val q30, int64_t scale, bool *exact)
{
    const i128 one = (i128)1 << IT2N_MEMB_FRAC;
    i128 s = (i128)q30 * scale, back;
    int64_t k = (int64_t)((s >= 0 ? s + one / 2 : s - one / 2) / one);
    back = (i128)k * one;
    back = (back >= 0 ? back + scale / 2 : back - scale / 2) / scale;
    *exact = back == (i128)q30;
    return k;
}

/* Word order and coordinate scale from the status block (once). */
static int mb_map(mb_conn *c)
{
    uint16_t r[IT2N_REGMAP_REG_INT32_ORDER - IT2N_REGMAP_REG_WORD_ORDER + 1];
    int rc;
    if (c->have_map) {
        return CTL_EXIT_OK;
    }
    rc = rd(c, IT2N_REGMAP_REG_WORD_ORDER, IT2N_REGMAP_REG_INT32_ORDER - IT2N_REGMAP_REG_WORD_ORDER + 1, r,
            "read status");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    c->word_order = r[0] & 3;
    c->coord_scale = r[IT2N_REGMAP_REG_COORD_SCALE - IT2N_REGMAP_REG_WORD_ORDER]
                         ? r[IT2N_REGMAP_REG_COORD_SCALE - IT2N_REGMAP_REG_WORD_ORDER]
                         : 100;
    c->int32_order = r[IT2N_REGMAP_REG_INT32_ORDER - IT2N_REGMAP_REG_WORD_ORDER] & 3;
    c->have_map = true;
    return CTL_EXIT_OK;
}

static int mb_status(void *p, ctl_status *st)
{
    mb_conn *c = p;
    uint16_t r[IT2N_REGMAP_REG_STATUS_END];
    int rc = rd(c, 0, IT2N_REGMAP_REG_STATUS_END, r, "read status");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    memset(st, 0, sizeof(*st));
    st->model = r[IT2N_REGMAP_REG_MODEL_ID];
    st->state = r[IT2N_REGMAP_REG_STATE];
    st->n = r[IT2N_REGMAP_REG_N];
    st->m = r[IT2N_REGMAP_REG_M];
    st->flags = r[IT2N_REGMAP_REG_FLAGS];
    st->present = r[IT2N_REGMAP_REG_PRESENT];
    st->required = r[IT2N_REGMAP_REG_REQUIRED];
    {
        /* kind, net size and u32 counts: absent from older daemons (02),
         * which serve the Bezier kind only */
        uint16_t k[IT2N_REGMAP_REG_STATUS_END - IT2N_REGMAP_REG_KIND], n32[4];
        if (modbus_read_registers(c->ctx, IT2N_REGMAP_REG_KIND, IT2N_REGMAP_REG_STATUS_END - IT2N_REGMAP_REG_KIND, k) ==
            (int)(IT2N_REGMAP_REG_STATUS_END - IT2N_REGMAP_REG_KIND)) {
            st->kind = k[0];
            st->net_rows = k[IT2N_REGMAP_REG_NET_ROWS - IT2N_REGMAP_REG_KIND];
            st->net_cols = k[IT2N_REGMAP_REG_NET_COLS - IT2N_REGMAP_REG_KIND];
            if (modbus_read_registers(c->ctx, IT2N_REGMAP_REG_PRESENT32, 4, n32) == 4) {
                st->present = it2n_regmap_get_u32(&n32[0], r[IT2N_REGMAP_REG_INT32_ORDER] & 3);
                st->required = it2n_regmap_get_u32(&n32[2], r[IT2N_REGMAP_REG_INT32_ORDER] & 3);
            }
        } else if (errno != EMBXILADD) {
            return mb_fail(c, "read status");
        } else {
            st->net_rows = st->state == CTL_ST_SOLVED ? st->n + 1u : 0u;
            st->net_cols = st->state == CTL_ST_SOLVED ? st->m + 1u : 0u;
        }
    }
    c->word_order = r[IT2N_REGMAP_REG_WORD_ORDER] & 3;
    c->int32_order = r[IT2N_REGMAP_REG_INT32_ORDER] & 3;
    st->generation = it2n_regmap_get_u32(&r[IT2N_REGMAP_REG_GENERATION], c->int32_order);
    st->last_error = (int16_t)r[IT2N_REGMAP_REG_LAST_ERR];
    c->coord_scale = r[IT2N_REGMAP_REG_COORD_SCALE] ? r[IT2N_REGMAP_REG_COORD_SCALE] : 100;
    c->have_map = true;
    return CTL_EXIT_OK;
}

/* The upload block of entry (i, j, fp); false (rej filled) when a value
 * is not exactly representable in the map's scaled integers. */
static bool upload_regs(const mb_conn *c, const cli_data *src, unsigned i, unsigned j, unsigned fp, uint16_t r[12],
                        it2n_errinfo *rej)
{
    it2n_val v[IT2N_CH_COUNT], fine[IT2N_CH_COUNT];
    unsigned ch;
    cli_data_get(src, i, j, fp, v);
    cli_data_get_fine(src, i, j, fp, fine);
    r[0] = (uint16_t)i;
    r[1] = (uint16_t)j;
    r[2] = (uint16_t)fp;
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        bool coord = ch < IT2N_CH_T;
        int64_t scale = coord ? c->coord_scale : IT2N_REGMAP_MEMB_SCALE;
        int64_t k;
        if (ch == IT2N_CH_Z && !(src->flags & IT2N_F_Z)) {
            v[ch] = 0;
        }
        bool exact;
        if (coord) {
            exact = exact_scaled(v[ch], scale, &k);
        } else {
            k = memb_scaled(fine[ch], scale, &exact);
            exact = exact && k <= INT32_MAX && k >= INT32_MIN;
        }
        if (!exact) {
            memset(rej, 0, sizeof(*rej));
            rej->code = IT2N_ERR_RANGE;
            rej->i = (int16_t)i;
            rej->j = (int16_t)j;
            rej->fp = (int8_t)fp;
            rej->ch = (int8_t)ch;
            rej->value = v[ch];
            rej->lo = scale; /* the caller names the scale */
            rej->hi = coord;
            return false;
        }
        if (coord) {
            it2n_regmap_put_u32(&r[3 + 2 * ch], (uint32_t)(int32_t)k, c->int32_order);
        } else {
            r[9 + ch - IT2N_CH_T] = (uint16_t)k;
        }
    }
    return true;
}

/* After a refused write: the daemon's last_error names the point. */
static void refused_detail(mb_conn *c, it2n_errinfo *rej)
{
    uint16_t r[4];
    memset(rej, 0, sizeof(*rej));
    rej->i = rej->j = -1;
    rej->fp = rej->ch = -1;
    if (modbus_read_registers(c->ctx, IT2N_REGMAP_REG_LAST_ERR, 4, r) == 4) {
        rej->code = (int16_t)r[0];
        rej->i = (int16_t)r[1];
        rej->j = (int16_t)r[2];
        rej->fp = (int8_t)(int16_t)r[3];
    }
}

static int mb_push(void *p, const cli_data *src, ctl_progress_fn progress, void *pctx, it2n_errinfo *rej)
{
    mb_conn *c = p;
    uint16_t cfg[4], up[12];
    unsigned i, j, fp, total = 0, done = 0, kind = 0;
    uint16_t kreg;
    int rc = mb_map(c);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    /* The unit's kind (a daemon without the register is Bezier only) */
    if (modbus_read_registers(c->ctx, IT2N_REGMAP_REG_KIND, 1, &kreg) == 1) {
        kind = kreg;
    } else if (errno != EMBXILADD) {
        return mb_fail(c, "read status");
    }
    if (kind != (src->bds != NULL ? IT2N_REGMAP_KIND_BSPLINE : IT2N_REGMAP_KIND_BEZIER)) {
        char where[32];
        snprintf(where, sizeof(where), "unit %d", modbus_get_slave(c->ctx));
        return ctl_wrong_kind(where, kind != IT2N_REGMAP_KIND_BEZIER, src, "sent");
    }
    /* Everything representable before the first write: a refused push
     * changes nothing. */
    for (i = 0; i <= src->n; i++) {
        for (j = 0; j <= src->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (cli_data_has(src, i, j, fp)) {
                    if (!upload_regs(c, src, i, j, fp, up, rej)) {
                        return CTL_REJECTED;
                    }
                    total++;
                }
            }
        }
    }
    cfg[0] = (uint16_t)src->n;
    cfg[1] = (uint16_t)src->m;
    cfg[2] = (uint16_t)src->flags;
    cfg[3] = IT2N_REGMAP_CMD_CLEAR;
    rc = wr(c, IT2N_REGMAP_REG_CFG_N, 4, cfg, "configure");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    for (i = 0; i <= src->n; i++) {
        for (j = 0; j <= src->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!cli_data_has(src, i, j, fp)) {
                    continue;
                }
                (void)upload_regs(c, src, i, j, fp, up, rej);
                if (modbus_write_registers(c->ctx, IT2N_REGMAP_REG_UP_I, 12, up) != 12) {
                    int e = errno;
                    if (exc_text(e) != NULL && e != EMBXILADD) {
                        refused_detail(c, rej);
                        return CTL_REJECTED;
                    }
                    errno = e;
                    return mb_fail(c, "upload");
                }
                done++;
                if (progress != NULL) {
                    progress(pctx, done, total);
                }
            }
        }
    }
    cfg[0] = IT2N_REGMAP_CMD_COMMIT;
    if (modbus_write_register(c->ctx, IT2N_REGMAP_REG_COMMAND, cfg[0]) != 1) {
        int e = errno;
        if (e == EMBXSFAIL) {
            refused_detail(c, rej);
            return CTL_REJECTED;
        }
        errno = e;
        return mb_fail(c, "commit");
    }
    return CTL_EXIT_OK;
}

/* Parameter as the daemon reads q_u (x10000) — exact when it matches. */
static bool par_scaled(it2n_par p, uint16_t *reg)
{
    uint16_t k = it2n_regmap_par_to_u16(p);
    if (it2n_regmap_par_from_u16(k) != p) {
        return false;
    }
    *reg = k;
    return true;
}

/* results_f32 (128..235) into pt; q_out_of_range from query_status. */
static void read_results(const mb_conn *c, const uint16_t *r, it2n_point *pt)
{
    unsigned fp, ch, k;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            pt->v[fp][ch] = f2q(it2n_regmap_get_f32(&r[(fp * IT2N_CH_COUNT + ch) * 2], c->word_order));
        }
    }
    for (k = 0; k < 3u; k++) {
        const uint16_t *s = &r[IT2N_REGMAP_REG_SUM_F32 - IT2N_REGMAP_REG_RES_F32];
        pt->sum.upper_min[k] = f2q(it2n_regmap_get_f32(&s[(0 * 3 + k) * 2], c->word_order));
        pt->sum.upper_max[k] = f2q(it2n_regmap_get_f32(&s[(1 * 3 + k) * 2], c->word_order));
        pt->sum.lower_min[k] = f2q(it2n_regmap_get_f32(&s[(2 * 3 + k) * 2], c->word_order));
        pt->sum.lower_max[k] = f2q(it2n_regmap_get_f32(&s[(3 * 3 + k) * 2], c->word_order));
    }
}

/* One FC 23 query: write regs at addr, read the float32 results, then the
 * query status (out of range bits, locate failures). */
static int query(mb_conn *c, unsigned addr, unsigned count, const uint16_t *w, it2n_point *pt, uint16_t *locfail)
{
    uint16_t r[IT2N_REGMAP_REG_SUM_F32 + 24 - IT2N_REGMAP_REG_RES_F32];
    uint16_t qs[IT2N_REGMAP_REG_QSTATUS_END - IT2N_REGMAP_REG_Q_KIND];
    unsigned n = (unsigned)(sizeof(r) / sizeof(r[0]));
    int rc;
    if (modbus_write_and_read_registers(c->ctx, (int)addr, (int)count, w, IT2N_REGMAP_REG_RES_F32, (int)n, r) !=
        (int)n) {
        return mb_fail(c, "query");
    }
    rc = rd(c, IT2N_REGMAP_REG_Q_KIND, IT2N_REGMAP_REG_QSTATUS_END - IT2N_REGMAP_REG_Q_KIND, qs, "query status");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    memset(pt, 0, sizeof(*pt));
    read_results(c, r, pt);
    pt->out_of_range = it2n_regmap_get_u32(&qs[IT2N_REGMAP_REG_Q_OOR - IT2N_REGMAP_REG_Q_KIND], c->int32_order);
    if (locfail != NULL) {
        *locfail = qs[IT2N_REGMAP_REG_Q_LOCFAIL - IT2N_REGMAP_REG_Q_KIND];
    }
    return CTL_EXIT_OK;
}

static int mb_eval(void *p, it2n_par *u, it2n_par *w, it2n_point *pt)
{
    mb_conn *c = p;
    uint16_t regs[4];
    int rc = mb_map(c);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (par_scaled(*u, &regs[0]) && par_scaled(*w, &regs[1])) {
        return query(c, IT2N_REGMAP_REG_Q_U16, 2, regs, pt, NULL);
    }
    /* float32: the daemon evaluates at llround(f * 2^32) */
    {
        float fu = (float)((double)*u / (double)IT2N_PAR_ONE);
        float fw = (float)((double)*w / (double)IT2N_PAR_ONE);
        it2n_regmap_put_f32(&regs[0], fu, c->word_order);
        it2n_regmap_put_f32(&regs[2], fw, c->word_order);
        *u = (it2n_par)llround((double)fu * (double)IT2N_PAR_ONE);
        *w = (it2n_par)llround((double)fw * (double)IT2N_PAR_ONE);
        return query(c, IT2N_REGMAP_REG_Q_UF, 4, regs, pt, NULL);
    }
}

static int mb_locate(void *p, it2n_val *x, it2n_val *y, ctl_loc res[IT2N_FP_COUNT])
{
    mb_conn *c = p;
    uint16_t regs[4], fail = 0;
    it2n_point pt;
    int64_t kx, ky;
    unsigned fp;
    int rc = mb_map(c);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (exact_scaled(*x, c->coord_scale, &kx) && exact_scaled(*y, c->coord_scale, &ky)) {
        it2n_regmap_put_u32(&regs[0], (uint32_t)(int32_t)kx, c->int32_order);
        it2n_regmap_put_u32(&regs[2], (uint32_t)(int32_t)ky, c->int32_order);
        rc = query(c, IT2N_REGMAP_REG_Q_XS, 4, regs, &pt, &fail);
    } else {
        float fx = (float)((double)*x / (double)IT2N_VAL_ONE);
        float fy = (float)((double)*y / (double)IT2N_VAL_ONE);
        it2n_regmap_put_f32(&regs[0], fx, c->word_order);
        it2n_regmap_put_f32(&regs[2], fy, c->word_order);
        *x = f2q(fx);
        *y = f2q(fy);
        rc = query(c, IT2N_REGMAP_REG_Q_XF, 4, regs, &pt, &fail);
    }
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        memset(&res[fp], 0, sizeof(res[fp]));
        res[fp].has_uw = false;
        res[fp].status = (fail & (1u << fp)) ? CTL_LOC_NOT_INSIDE : CTL_LOC_INSIDE;
        memcpy(res[fp].v, pt.v[fp], sizeof(res[fp].v));
    }
    return CTL_EXIT_OK;
}

static int mb_net(void *p, const ctl_status *st, ctl_net *net)
{
    mb_conn *c = p;
    uint16_t r[IT2N_REGMAP_DIM * IT2N_REGMAP_CH * 2];
    unsigned fp, i, j, ch, cnt = (st->m + 1u) * IT2N_REGMAP_CH * 2u;
    int rc = mb_map(c);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    memset(net, 0, sizeof(*net));
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if ((st->flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
            continue;
        }
        for (i = 0; i <= st->n; i++) {
            unsigned addr = IT2N_REGMAP_REG_CTRL + ((fp * IT2N_REGMAP_DIM + i) * IT2N_REGMAP_DIM) * IT2N_REGMAP_CH * 2u;
            rc = rd(c, addr, cnt, r, "read control net");
            if (rc != CTL_EXIT_OK) {
                return rc;
            }
            for (j = 0; j <= st->m; j++) {
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    (*net)[fp][i][j][ch] = f2q(it2n_regmap_get_f32(&r[(j * IT2N_REGMAP_CH + ch) * 2], c->word_order));
                }
            }
        }
    }
    return CTL_EXIT_OK;
}

static int mb_sample(void *p, const ctl_status *st, unsigned rows, unsigned cols, ctl_sample_fn cb, void *ctx)
{
    unsigned r, cc;
    (void)st;
    for (r = 0; r < rows; r++) {
        for (cc = 0; cc < cols; cc++) {
            it2n_par u = ctl_grid_par(r, rows), w = ctl_grid_par(cc, cols);
            it2n_point pt;
            int rc = mb_eval(p, &u, &w, &pt);
            if (rc != CTL_EXIT_OK) {
                return rc;
            }
            rc = cb(ctx, r, cc, u, w, &pt);
            if (rc != 0) {
                return rc;
            }
        }
    }
    return CTL_EXIT_OK;
}

static int mb_wait(void *p, uint32_t gen, int timeout_ms, ctl_status *st)
{
    mb_conn *c = p;
    struct timespec t0, t1;
    int poll = timeout_ms < 100 ? timeout_ms : 100;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (;;) {
        long ms;
        int rc = mb_status(c, st);
        if (rc != CTL_EXIT_OK || st->generation != gen) {
            return rc;
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        ms = (t1.tv_sec - t0.tv_sec) * 1000L + (t1.tv_nsec - t0.tv_nsec) / 1000000L;
        if (ms >= timeout_ms) {
            return CTL_EXIT_OK;
        }
        {
            struct timespec d = {0, (long)poll * 1000000L};
            nanosleep(&d, NULL);
        }
    }
}

static void mb_close(void *p)
{
    mb_conn *c = p;
    modbus_close(c->ctx);
    modbus_free(c->ctx);
    free(c);
}

/* One row of one net through the coefficient page (docs/registers.md):
 * st->net_cols values into out, Q24 from float32. */
static int mb_coef_row(void *p, const ctl_status *st, unsigned fp, unsigned ch, unsigned row, it2n_val *out)
{
    mb_conn *c = p;
    uint16_t sel[3], r[2u * IT2N_REGMAP_WIN_COLS];
    unsigned s, done = 0, total = 2u * st->net_cols;
    int rc = mb_map(c);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    sel[0] = (uint16_t)fp;
    sel[1] = (uint16_t)ch;
    sel[2] = (uint16_t)row;
    rc = wr(c, IT2N_REGMAP_REG_PG_FP, 3, sel, "select coefficient page");
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    while (done < total) {
        unsigned cnt = total - done > 124u ? 124u : total - done;
        rc = rd(c, IT2N_REGMAP_REG_WIN + done, cnt, &r[done], "read coefficients");
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        done += cnt;
    }
    for (s = 0; s < st->net_cols; s++) {
        out[s] = f2q(it2n_regmap_get_f32(&r[2u * s], c->word_order));
    }
    return CTL_EXIT_OK;
}

static const ctl_ops mb_ops = {"modbus", mb_status, mb_push, mb_eval,  mb_locate,
                               mb_net,   mb_sample, mb_wait, mb_close, mb_coef_row};

const char *ctl_tcp_split(const char *t, char *host, size_t hn, char *port, size_t pn)
{
    const char *colon, *end;
    size_t hl;
    unsigned long v;
    char *stop;

    if (t[0] == '[') { /* [v6]:port */
        const char *rb = strchr(t, ']');
        if (rb == NULL) {
            return "the address has no closing ']' (expected [V6]:PORT)";
        }
        hl = (size_t)(rb - t - 1);
        t++;
        colon = rb[1] == ':' ? rb + 1 : NULL;
        if (colon == NULL && rb[1] != '\0') {
            return "expected ':' after ']' (expected [V6]:PORT)";
        }
    } else {
        colon = strrchr(t, ':');
        if (colon != NULL && strchr(t, ':') != colon) {
            return "an IPv6 address needs brackets: [V6]:PORT";
        }
        hl = colon ? (size_t)(colon - t) : strlen(t);
    }
    if (hl == 0) {
        return "the host is empty (expected HOST:PORT)";
    }
    if (hl >= hn) {
        return "the host name is too long";
    }
    memcpy(host, t, hl);
    host[hl] = '\0';
    end = colon ? colon + 1 : "1502";
    errno = 0;
    v = strtoul(end, &stop, 10);
    if (end[0] < '0' || end[0] > '9' || *stop != '\0' || errno != 0 || v < 1 || v > 65535 || strlen(end) >= pn) {
        return "the port is not a number 1..65535 (expected HOST:PORT)";
    }
    snprintf(port, pn, "%lu", v);
    return NULL;
}

/* Name errors are told apart from an absent daemon: an unresolvable host
 * is never "connection refused (is it2nd running?)". */
static bool tcp_resolves(const char *host, const char *port)
{
    struct addrinfo hints, *res = NULL;
    int e;

    memset(&hints, 0, sizeof(hints));
    hints.ai_socktype = SOCK_STREAM;
    e = getaddrinfo(host, port, &hints, &res);
    if (e != 0) {
        fprintf(stderr,
                "it2nctl: cannot resolve host '%s': %s (check the "
                "name in --tcp HOST:PORT, or give an address)\n",
                host, gai_strerror(e));
        return false;
    }
    freeaddrinfo(res);
    return true;
}

void *ctl_modbus_open(const ctl_conn_opts *o, const ctl_ops **ops, int *rc)
{
    mb_conn *c = calloc(1, sizeof(*c));
    char host[128], port[16];
    if (c == NULL) {
        fprintf(stderr, "it2nctl: out of memory\n");
        *rc = CTL_EXIT_COMM;
        return NULL;
    }
    *rc = CTL_EXIT_COMM;
    if (o->rtu != NULL) {
        c->ctx = modbus_new_rtu(o->rtu, (int)o->baud, o->parity, 8, (int)o->stop_bits);
        snprintf(c->where, sizeof(c->where), "%s unit %u", o->rtu, o->unit);
    } else {
        const char *why = ctl_tcp_split(o->tcp ? o->tcp : "127.0.0.1:1502", host, sizeof(host), port, sizeof(port));
        if (why != NULL) { /* parse_args checked it: not reached */
            fprintf(stderr, "it2nctl: --tcp '%s': %s\n", o->tcp, why);
            free(c);
            *rc = CTL_EXIT_USAGE;
            return NULL;
        }
        if (!tcp_resolves(host, port)) {
            free(c);
            return NULL;
        }
        c->ctx = modbus_new_tcp_pi(host, port);
        snprintf(c->where, sizeof(c->where), "%s%s%s:%s unit %u", strchr(host, ':') ? "[" : "", host,
                 strchr(host, ':') ? "]" : "", port, o->unit);
    }
    if (c->ctx == NULL) {
        fprintf(stderr, "it2nctl: %s: %s\n", c->where, modbus_strerror(errno));
        free(c);
        return NULL;
    }
    modbus_set_slave(c->ctx, (int)o->unit);
    modbus_set_response_timeout(c->ctx, o->timeout_ms / 1000u, (o->timeout_ms % 1000u) * 1000u);
    if (modbus_connect(c->ctx) != 0) {
        int e = errno;
        if (o->rtu != NULL) {
            fprintf(stderr, "it2nctl: cannot open serial device %s: %s (%s)\n", o->rtu, modbus_strerror(e),
                    e == ENOENT   ? "check the path in --rtu DEVICE, e.g. "
                                    "ls /dev/serial/by-id/"
                    : e == EACCES ? "add yourself to the dialout group, or "
                                    "run as a user allowed to open it"
                                  : "is another program holding it?");
        } else {
            fprintf(stderr,
                    "it2nctl: cannot connect to %s: %s (is it2nd "
                    "running? --tcp HOST:PORT, --rtu DEVICE or "
                    "--link DEVICE)\n",
                    c->where, modbus_strerror(e));
        }
        modbus_free(c->ctx);
        free(c);
        return NULL;
    }
    *ops = &mb_ops;
    *rc = CTL_EXIT_OK;
    return c;
}
