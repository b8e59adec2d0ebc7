/* mb_map.c — see mb_map.h. Floats are used here only to present results;
 * the model and every input stay in the core's fixed point. */
#include "mb_map.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "errs.h"
#include "it2n_regmap.h"

_Static_assert(IT2N_DIM <= IT2N_REGMAP_DIM, "control-net stride of the map too small");
_Static_assert(IT2N_REGMAP_REG_GRID_F32_END - IT2N_REGMAP_REG_GRID_F32 <=
                   IT2N_REGMAP_REG_CTRL_END - IT2N_REGMAP_REG_CTRL,
               "scratch buffer holds the largest block");
_Static_assert(IT2N_VAL_FRAC == IT2N_REGMAP_Q24_FRAC && IT2N_PAR_FRAC == IT2N_REGMAP_PAR_FRAC,
               "the map's codecs carry the core's fixed point");
_Static_assert(IT2N_FP_COUNT == IT2N_REGMAP_FP && IT2N_CH_COUNT == IT2N_REGMAP_CH, "map footprint/channel counts");

/* The float result block is it2n_point's values then its summary in
 * sum_value order, contiguous in the struct: converted in one call. */
#define RES_F32_VALUES (IT2N_FP_COUNT * IT2N_CH_COUNT + 12)
_Static_assert(IT2N_REGMAP_REG_SUM_F32 - IT2N_REGMAP_REG_RES_F32 == 2 * IT2N_FP_COUNT * IT2N_CH_COUNT &&
                   offsetof(it2n_point, sum) == sizeof(it2n_val) * IT2N_FP_COUNT * IT2N_CH_COUNT &&
                   offsetof(it2n_summary, upper_min) == 0 &&
                   offsetof(it2n_summary, upper_max) == 3 * sizeof(it2n_val) &&
                   offsetof(it2n_summary, lower_min) == 6 * sizeof(it2n_val) &&
                   offsetof(it2n_summary, lower_max) == 9 * sizeof(it2n_val),
               "results_f32 is it2n_point's v then sum, in sum_value order");

/* clang-format off */
#define QIDX(a) ((a) - IT2N_REGMAP_REG_Q_U16)
/* clang-format on */

/* u32/i32 registers follow int32_word_order ([modbus]; by default the
 * float order, so a CDAB PLC sees CDAB everywhere). */
#define put_u32(out, v) it2n_regmap_put_u32((out), (v), (unsigned)o->int32_order)
#define get_u32(in) it2n_regmap_get_u32((in), (unsigned)o->int32_order)

static uint16_t sat16(unsigned v)
{
    return (uint16_t)(v > 0xFFFFu ? 0xFFFFu : v);
}

/* Make sure q's cached result matches the model's current generation. */
static int query_result(struct model *md, struct mb_map_query *q)
{
    if (md->state != IT2N_REGMAP_STATE_SOLVED)
        return MB_MAP_BUSY;
    if (q->kind == 0)
        return MB_MAP_OK;
    if (q->valid && q->model_inst == md->instance && q->gen == md->gen)
        return MB_MAP_OK;
    q->locfail = 0;
    if (q->kind == 1) {
        /* it2n_eval writes every value, the summary and the flags */
        if (models_eval(md, q->u, q->w, &q->pt, NULL) != IT2N_OK)
            return MB_MAP_DEVICE_FAILURE;
    } else {
        memset(&q->pt, 0, sizeof q->pt);
        it2n_locate_result lr;
        if (models_locate(md, q->x, q->y, &lr, NULL) != IT2N_OK)
            return MB_MAP_DEVICE_FAILURE;
        it2n_val mn[4][3], mx[4][3];
        static const int up[3] = {IT2N_FP_LL, IT2N_FP_D, IT2N_FP_RR};
        static const int low[3] = {IT2N_FP_LR, IT2N_FP_D, IT2N_FP_RL};
        for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
            if (!models_has_fp(md, fp))
                continue;
            memcpy(q->pt.v[fp], lr.fp[fp].v, sizeof q->pt.v[fp]);
            if (lr.fp[fp].status != IT2N_LOC_INSIDE)
                q->locfail |= (uint16_t)(1u << fp);
            for (unsigned k = 0; k < 3; k++) {
                it2n_val t = lr.fp[fp].v[IT2N_CH_T + k];
                if (t < 0 || t > IT2N_VAL_ONE)
                    q->pt.out_of_range |= 1u << (fp * 3 + k);
            }
        }
        /* Interval summary from the located surface values (the core's
         * summary is per (u, w); here each footprint has its own). */
        for (int k = 0; k < 3; k++) {
            const int *sets[2] = {up, low};
            for (int s = 0; s < 2; s++) {
                it2n_val lo = 0, hi = 0;
                int first = 1;
                for (int e = 0; e < 3; e++) {
                    if (!models_has_fp(md, (unsigned)sets[s][e]))
                        continue;
                    it2n_val t = q->pt.v[sets[s][e]][IT2N_CH_T + k];
                    if (first || t < lo)
                        lo = t;
                    if (first || t > hi)
                        hi = t;
                    first = 0;
                }
                mn[s][k] = lo;
                mx[s][k] = hi;
            }
            q->pt.sum.upper_min[k] = mn[0][k];
            q->pt.sum.upper_max[k] = mx[0][k];
            q->pt.sum.lower_min[k] = mn[1][k];
            q->pt.sum.lower_max[k] = mx[1][k];
        }
    }
    q->valid = 1;
    q->model_inst = md->instance;
    q->gen = md->gen;
    return MB_MAP_OK;
}

static it2n_val sum_value(const it2n_summary *s, unsigned idx)
{
    unsigned set = idx / 3, k = idx % 3;
    switch (set) {
    case 0: return s->upper_min[k];
    case 1: return s->upper_max[k];
    case 2: return s->lower_min[k];
    default: return s->lower_max[k];
    }
}

/* The sample grid cache (D footprint T, I, F in Q24 per node), the Modbus
 * side's own: one entry per model id, valid for the model instance and
 * generation and the grid size it was computed for (a model put back
 * after a failed batch has a new instance, so a grid of the undone change
 * is never served). Grown on demand; a model removed leaves an entry no
 * later model instance can match. */
struct grid_cache {
    int id, valid;
    uint32_t inst, gen;
    unsigned rows, cols;
    it2n_val v[IT2N_REGMAP_GRID_MAX_NODES][3];
};
static struct grid_cache *grids;
static int ngrids;

static int grid_cb(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w, const it2n_point *pt)
{
    struct grid_cache *g = ctx;
    (void)u;
    (void)w;
    for (int k = 0; k < 3; k++)
        g->v[r * g->cols + c][k] = pt->v[IT2N_FP_D][IT2N_CH_T + k];
    return 0;
}

/* md's grid, computed if the cache does not hold it; NULL on failure. */
static const struct grid_cache *grid_of(const struct model *md, unsigned rows, unsigned cols)
{
    struct grid_cache *g = NULL;
    for (int k = 0; k < ngrids && !g; k++)
        if (grids[k].id == md->id)
            g = &grids[k];
    if (!g) {
        struct grid_cache *n = realloc(grids, (size_t)(ngrids + 1) * sizeof *grids);
        if (!n)
            return NULL;
        grids = n;
        g = &grids[ngrids++];
        g->id = md->id;
        g->valid = 0;
    }
    if (g->valid && g->inst == md->instance && g->gen == md->gen && g->rows == rows && g->cols == cols)
        return g;
    g->valid = 0;
    g->rows = rows;
    g->cols = cols;
    if (rows * cols > IT2N_REGMAP_GRID_MAX_NODES || models_sample(md, rows, cols, grid_cb, g, NULL) != IT2N_OK)
        return NULL;
    g->inst = md->instance;
    g->gen = md->gen;
    g->valid = 1;
    return g;
}

/* A sample-grid read of `span` registers (regs_per_node per node) can be
 * answered: inside the configured nodes, model solved, grid cache current
 * (*g set). */
static int grid_ready(struct model *md, const struct mb_map_opts *o, unsigned span, unsigned regs_per_node,
                      const struct grid_cache **g)
{
    if (span > o->grid_rows * o->grid_cols * regs_per_node)
        return MB_MAP_ILLEGAL_ADDRESS;
    if (md->state != IT2N_REGMAP_STATE_SOLVED)
        return MB_MAP_BUSY;
    if (!(*g = grid_of(md, o->grid_rows, o->grid_cols)))
        return MB_MAP_DEVICE_FAILURE;
    return MB_MAP_OK;
}

/* Grid values the x10000 view clamps (the saturation flag of the scaled
 * sample grid); 0 while the model is not solved. */
static uint16_t grid_saturated(struct model *md, const struct mb_map_opts *o)
{
    unsigned nodes = o->grid_rows * o->grid_cols, count = 0;
    const struct grid_cache *g;
    if (grid_ready(md, o, 0, 1u, &g) != MB_MAP_OK)
        return 0;
    for (unsigned nd = 0; nd < nodes; nd++)
        for (unsigned k = 0; k < 3; k++) {
            int sat = 0;
            (void)it2n_regmap_q24_to_scaled(g->v[nd][k], IT2N_REGMAP_MEMB_SCALE, -32767, 32767, &sat);
            count += sat != 0;
        }
    return (uint16_t)(count > 65535u ? 65535u : count);
}

static void sync_views(struct mb_map_query *q);

_Static_assert(2 * RES_F32_VALUES == IT2N_REGMAP_REG_SUM_F32 + 24u - IT2N_REGMAP_REG_RES_F32,
               "the conversion of the results fills the whole results_f32 block");

/* Fill registers [start, end) of one block into buf (indexed from start). */
static int fill_block(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const it2n_regmap_block *b,
                      uint16_t *buf, unsigned from, unsigned to)
{
    unsigned len = b->end - b->start;
    int rc, sat;
    /* zeros where a block leaves registers unset; the float results are
     * all written when there are results (every FC 23 answer) */
    if (b->start != IT2N_REGMAP_REG_RES_F32)
        memset(buf, 0, len * sizeof *buf);
    switch (b->start) {
    case IT2N_REGMAP_REG_MAP_VERSION: {
        uint16_t *r = buf;
        r[IT2N_REGMAP_REG_MAP_VERSION] = IT2N_REGMAP_VERSION;
        r[IT2N_REGMAP_REG_STATE] = (uint16_t)md->state;
        r[IT2N_REGMAP_REG_N] = (uint16_t)models_n(md);
        r[IT2N_REGMAP_REG_M] = (uint16_t)models_m(md);
        r[IT2N_REGMAP_REG_FLAGS] = (uint16_t)models_flags(md);
        r[IT2N_REGMAP_REG_PRESENT] = sat16(models_present(md));
        r[IT2N_REGMAP_REG_REQUIRED] = sat16(models_required(md));
        put_u32(&r[IT2N_REGMAP_REG_GENERATION], md->gen);
        r[IT2N_REGMAP_REG_LAST_ERR] = (uint16_t)(int16_t)md->last_err.code;
        r[IT2N_REGMAP_REG_ERR_I] = (uint16_t)(md->last_err.code ? md->last_err.i : -1);
        r[IT2N_REGMAP_REG_ERR_J] = (uint16_t)(md->last_err.code ? md->last_err.j : -1);
        r[IT2N_REGMAP_REG_ERR_FP] = (uint16_t)(md->last_err.code ? md->last_err.fp : -1);
        put_u32(&r[IT2N_REGMAP_REG_POINTS_RX], md->points_rx);
        put_u32(&r[IT2N_REGMAP_REG_SOLVES], md->solves);
        put_u32(&r[IT2N_REGMAP_REG_REQUESTS], md->mb.requests);
        put_u32(&r[IT2N_REGMAP_REG_EXCEPTIONS], md->mb.exceptions);
        r[IT2N_REGMAP_REG_WORD_ORDER] = (uint16_t)o->word_order;
        r[IT2N_REGMAP_REG_COORD_SCALE] = (uint16_t)o->coord_scale;
        r[IT2N_REGMAP_REG_GRID_ROWS] = (uint16_t)o->grid_rows;
        r[IT2N_REGMAP_REG_GRID_COLS] = (uint16_t)o->grid_cols;
        r[IT2N_REGMAP_REG_MODEL_ID] = (uint16_t)md->id;
        r[IT2N_REGMAP_REG_GRID_SAT] = grid_saturated(md, o);
        r[IT2N_REGMAP_REG_INT32_ORDER] = (uint16_t)o->int32_order;
        r[IT2N_REGMAP_REG_KIND] = md->kind == MODEL_BSPLINE ? IT2N_REGMAP_KIND_BSPLINE : IT2N_REGMAP_KIND_BEZIER;
        r[IT2N_REGMAP_REG_NET_ROWS] = (uint16_t)(md->state == IT2N_REGMAP_STATE_SOLVED ? models_net_rows(md) : 0u);
        r[IT2N_REGMAP_REG_NET_COLS] = (uint16_t)(md->state == IT2N_REGMAP_STATE_SOLVED ? models_net_cols(md) : 0u);
        return MB_MAP_OK;
    }
    case IT2N_REGMAP_REG_PRESENT32:
        put_u32(&buf[0], models_present(md));
        put_u32(&buf[IT2N_REGMAP_REG_REQUIRED32 - IT2N_REGMAP_REG_PRESENT32], models_required(md));
        return MB_MAP_OK;
    case IT2N_REGMAP_REG_PG_FP: memcpy(buf, q->page, sizeof q->page); return MB_MAP_OK;
    case IT2N_REGMAP_REG_WIN: {
        unsigned fp = q->page[0], ch = q->page[1], row = q->page[2], cols = models_net_cols(md);
        unsigned first = (from - b->start) / 2, last = (to - b->start + 1) / 2;
        if (md->state != IT2N_REGMAP_STATE_SOLVED)
            return MB_MAP_BUSY;
        if (row >= models_net_rows(md) || !models_has_fp(md, fp))
            return MB_MAP_OK; /* zeros */
        for (unsigned s = first; s < last && s < cols; s++)
            it2n_regmap_put_f32(&buf[s * 2], it2n_regmap_q24_to_f32(models_coef(md, row, s, fp, ch)), o->word_order);
        return MB_MAP_OK;
    }
    case IT2N_REGMAP_REG_CFG_N:
        buf[0] = (uint16_t)models_n(md);
        buf[1] = (uint16_t)models_m(md);
        buf[2] = (uint16_t)models_flags(md);
        buf[3] = 0;
        return MB_MAP_OK;
    case IT2N_REGMAP_REG_UP_I: memcpy(buf, md->mb.upload, sizeof md->mb.upload); return MB_MAP_OK;
    case IT2N_REGMAP_REG_Q_U16:
        if (q->views_due)
            sync_views(q);
        memcpy(buf, q->regs, sizeof q->regs);
        return MB_MAP_OK;
    case IT2N_REGMAP_REG_Q_KIND:
        rc = query_result(md, q);
        if (rc == MB_MAP_BUSY) { /* status stays readable while unsolved */
            buf[0] = (uint16_t)q->kind;
            return MB_MAP_OK;
        }
        if (rc)
            return rc;
        buf[0] = (uint16_t)q->kind;
        put_u32(&buf[IT2N_REGMAP_REG_Q_GEN - IT2N_REGMAP_REG_Q_KIND], q->kind ? q->gen : 0);
        buf[IT2N_REGMAP_REG_Q_LOCFAIL - IT2N_REGMAP_REG_Q_KIND] = q->locfail;
        put_u32(&buf[IT2N_REGMAP_REG_Q_OOR - IT2N_REGMAP_REG_Q_KIND], q->pt.out_of_range);
        return MB_MAP_OK;
    case IT2N_REGMAP_REG_RES_F32:
        if ((rc = query_result(md, q)) != MB_MAP_OK)
            return rc;
        if (q->kind == 0) {
            memset(buf, 0, len * sizeof *buf);
            return MB_MAP_OK;
        }
        /* The values then the summary, as they lie in it2n_point: one
         * conversion of 54 (asserted at the top of the file). */
        it2n_regmap_put_q24_f32s(buf, &q->pt.v[0][0], RES_F32_VALUES, o->word_order);
        return MB_MAP_OK;
    case IT2N_REGMAP_REG_RES_SCALED:
        if ((rc = query_result(md, q)) != MB_MAP_OK)
            return rc;
        if (q->kind == 0)
            return MB_MAP_OK;
        for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
            uint16_t *r = &buf[fp * IT2N_REGMAP_REG_RES_SCALED_STRIDE];
            uint16_t mask = 0;
            for (unsigned ch = 0; ch < 3; ch++) {
                sat = 0;
                int64_t v = it2n_regmap_q24_to_scaled(q->pt.v[fp][ch], o->coord_scale, INT32_MIN, INT32_MAX, &sat);
                put_u32(&r[ch * 2], (uint32_t)(int32_t)v);
                mask = (uint16_t)(mask | (sat ? 1u << ch : 0u));
            }
            for (unsigned k = 0; k < 3; k++) {
                sat = 0;
                int64_t v =
                    it2n_regmap_q24_to_scaled(q->pt.v[fp][IT2N_CH_T + k], IT2N_REGMAP_MEMB_SCALE, -32767, 32767, &sat);
                r[6 + k] = (uint16_t)(int16_t)v;
                mask = (uint16_t)(mask | (sat ? 1u << (3 + k) : 0u));
            }
            buf[IT2N_REGMAP_REG_SAT - IT2N_REGMAP_REG_RES_SCALED + fp] = mask;
        }
        {
            uint16_t mask = 0;
            for (unsigned s = 0; s < 12; s++) {
                sat = 0;
                int64_t v =
                    it2n_regmap_q24_to_scaled(sum_value(&q->pt.sum, s), IT2N_REGMAP_MEMB_SCALE, -32767, 32767, &sat);
                buf[IT2N_REGMAP_REG_SUM_SCALED - IT2N_REGMAP_REG_RES_SCALED + s] = (uint16_t)(int16_t)v;
                mask = (uint16_t)(mask | (sat ? 1u << s : 0u));
            }
            buf[IT2N_REGMAP_REG_SAT_SUM - IT2N_REGMAP_REG_RES_SCALED] = mask;
        }
        return MB_MAP_OK;
    case IT2N_REGMAP_REG_GRID: {
        unsigned nodes = o->grid_rows * o->grid_cols;
        const struct grid_cache *g;
        int ready = grid_ready(md, o, to - b->start, 3u, &g);
        if (ready != MB_MAP_OK)
            return ready;
        for (unsigned nd = 0; nd < nodes; nd++)
            for (unsigned k = 0; k < 3; k++) {
                sat = 0;
                buf[nd * 3 + k] = (uint16_t)(int16_t)it2n_regmap_q24_to_scaled(g->v[nd][k], IT2N_REGMAP_MEMB_SCALE,
                                                                               -32767, 32767, &sat);
            }
        return MB_MAP_OK;
    }
    case IT2N_REGMAP_REG_GRID_F32: {
        unsigned nodes = o->grid_rows * o->grid_cols;
        const struct grid_cache *g;
        int ready = grid_ready(md, o, to - b->start, 6u, &g);
        if (ready != MB_MAP_OK)
            return ready;
        for (unsigned nd = 0; nd < nodes; nd++)
            for (unsigned k = 0; k < 3; k++)
                it2n_regmap_put_f32(&buf[(nd * 3 + k) * 2], it2n_regmap_q24_to_f32(g->v[nd][k]), o->word_order);
        return MB_MAP_OK;
    }
    case IT2N_REGMAP_REG_CTRL: {
        if (md->kind != MODEL_BEZIER)
            return MB_MAP_ILLEGAL_ADDRESS; /* its nets are read through coef_window */
        if (md->state != IT2N_REGMAP_STATE_SOLVED)
            return MB_MAP_BUSY;
        /* Only the requested span: the block is 5376 registers. */
        unsigned first = (from - b->start) / 2, last = (to - b->start + 1) / 2;
        for (unsigned e = first; e < last; e++) {
            unsigned ch = e % 6, j = (e / 6) % 8, i = (e / 48) % 8, fp = e / 384;
            if (i <= md->mdl.n && j <= md->mdl.m && it2n_model_has_fp(&md->mdl, fp))
                it2n_regmap_put_f32(&buf[e * 2], it2n_regmap_q24_to_f32(it2n_model_ctrl(&md->mdl, i, j, fp, ch)),
                                    o->word_order);
        }
        return MB_MAP_OK;
    }
    default: return MB_MAP_ILLEGAL_ADDRESS;
    }
}

int mb_map_read(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, unsigned addr, unsigned count,
                uint16_t *out)
{
    return mb_map_read_in(md, q, o, it2n_regmap_find(addr, count), addr, count, out);
}

int mb_map_read_in(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const it2n_regmap_block *b,
                   unsigned addr, unsigned count, uint16_t *out)
{
    static uint16_t buf[IT2N_REGMAP_REG_CTRL_END - IT2N_REGMAP_REG_CTRL]; /* the largest block */
    int rc;
    if (!b)
        return MB_MAP_ILLEGAL_ADDRESS;
    /* The whole float results block (what an FC 23 query reads) is
     * converted in place: fill_block writes none of it before its checks,
     * so out is left as it was on an exception, as through buf. */
    if (b->start == IT2N_REGMAP_REG_RES_F32 && addr == b->start && count == (unsigned)(b->end - b->start))
        return fill_block(md, q, o, b, out, addr, addr + count);
    rc = fill_block(md, q, o, b, buf, addr, addr + count);
    if (rc)
        return rc;
    memcpy(out, &buf[addr - b->start], count * sizeof *out);
    return MB_MAP_OK;
}

static int map_core_err(int code)
{
    switch (code) {
    case IT2N_ERR_INVAL:
    case IT2N_ERR_RANGE:
    case IT2N_ERR_DUPLICATE: return MB_MAP_ILLEGAL_VALUE;
    case IT2N_ERR_MISSING: return MB_MAP_BUSY;
    default: return MB_MAP_DEVICE_FAILURE;
    }
}

/* A refused write says why in the model's last_error (status register 9,
 * with i, j, fp): exc is the exception answered, code the it2n code. */
static int refused(struct model *md, int exc, int code, int i, int j, int fp)
{
    memset(&md->last_err, 0, sizeof md->last_err);
    md->last_err.code = code;
    md->last_err.i = (int16_t)i;
    md->last_err.j = (int16_t)j;
    md->last_err.fp = (int8_t)fp;
    md->last_err.ch = -1;
    return exc;
}

/* A model operation failed with err: that is the report. */
static int refused_err(struct model *md, const it2n_errinfo *err)
{
    md->last_err = *err;
    return map_core_err(err->code);
}

void mb_map_refused(struct model *md, int exc)
{
    refused(md, exc, exc == MB_MAP_BUSY ? IT2N_ERR_STATE : IT2N_ERR_INVAL, -1, -1, -1);
}

static int write_config(struct model *md, unsigned addr, unsigned count, const uint16_t *v, int *persisted)
{
    unsigned n = models_n(md), m = models_m(md), flags = models_flags(md), cmd = 0;
    unsigned max = md->kind == MODEL_BSPLINE ? IT2N_BSPLINE_MAX_N : IT2N_MAX_DEGREE;
    it2n_errinfo err;
    int rc;
    for (unsigned k = 0; k < count; k++) {
        unsigned a = addr + k;
        if (a == IT2N_REGMAP_REG_CFG_N)
            n = v[k];
        else if (a == IT2N_REGMAP_REG_CFG_M)
            m = v[k];
        else if (a == IT2N_REGMAP_REG_CFG_FLAGS)
            flags = v[k];
        else
            cmd = v[k];
    }
    if (n < 1 || n > max || m < 1 || m > max || (flags & ~IT2N_F_ALL) || cmd > IT2N_REGMAP_CMD_CLEAR)
        return refused(md, MB_MAP_ILLEGAL_VALUE, IT2N_ERR_INVAL, -1, -1, -1);
    int changed = n != models_n(md) || m != models_m(md) || flags != models_flags(md);
    if (cmd == IT2N_REGMAP_CMD_COMMIT && changed)
        return refused(md, MB_MAP_BUSY, IT2N_ERR_MISSING, -1, -1, -1); /* a fresh configuration has no points */
    if (cmd == IT2N_REGMAP_CMD_COMMIT && models_missing(md) != 0)
        return refused(md, MB_MAP_BUSY, IT2N_ERR_MISSING, -1, -1, -1);
    if (changed) {
        rc = models_configure(md, n, m, flags, &err);
        if (rc)
            return refused_err(md, &err);
        *persisted = 1;
    }
    if (cmd == IT2N_REGMAP_CMD_CLEAR) {
        if ((rc = models_clear(md)) != 0)
            return refused(md, MB_MAP_DEVICE_FAILURE, rc, -1, -1, -1);
        *persisted = 1;
    } else if (cmd == IT2N_REGMAP_CMD_COMMIT) {
        rc = models_commit(md, &err);
        if (rc)
            return refused_err(md, &err);
        *persisted = 1;
    }
    return MB_MAP_OK;
}

static int write_upload(struct model *md, const struct mb_map_opts *o, unsigned addr, unsigned count, const uint16_t *v,
                        int *persisted)
{
    it2n_val vals[IT2N_CH_COUNT] = {0};
    it2n_errinfo err;
    int rc;
    if (addr != IT2N_REGMAP_REG_UP_I || count != IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I)
        return refused(md, MB_MAP_ILLEGAL_VALUE, IT2N_ERR_INVAL, -1, -1, -1);
/* clang-format off */
#define UP(a) v[(a) - IT2N_REGMAP_REG_UP_I]
    /* clang-format on */
    unsigned i = UP(IT2N_REGMAP_REG_UP_I), j = UP(IT2N_REGMAP_REG_UP_J), fp = UP(IT2N_REGMAP_REG_UP_FP);
    if (i > models_n(md) || j > models_m(md) || fp >= IT2N_FP_COUNT)
        return refused(md, MB_MAP_ILLEGAL_VALUE, IT2N_ERR_INVAL, i > 0x7FFF ? -1 : (int)i, j > 0x7FFF ? -1 : (int)j,
                       fp >= IT2N_FP_COUNT ? -1 : (int)fp);
    for (unsigned c = 0; c < 3; c++)
        vals[c] = it2n_regmap_q24_from_scaled((int32_t)get_u32(&UP(IT2N_REGMAP_REG_UP_X + 2 * c)), o->coord_scale);
    /* memberships into Q30 (the fine layout): round(t 2^30 / 10000), the
     * value 'it2n' reads from the same 4-decimal CSV */
    for (unsigned k = 0; k < 3; k++) {
        unsigned t = UP(IT2N_REGMAP_REG_UP_T + k);
        if (t > IT2N_REGMAP_MEMB_SCALE) {
            refused(md, MB_MAP_ILLEGAL_VALUE, IT2N_ERR_RANGE, (int)i, (int)j, (int)fp);
            md->last_err.ch = (int8_t)(IT2N_CH_T + k);
            md->last_err.value = it2n_regmap_q24_from_scaled(t, IT2N_REGMAP_MEMB_SCALE);
            md->last_err.lo = 0;
            md->last_err.hi = IT2N_VAL_ONE;
            return MB_MAP_ILLEGAL_VALUE;
        }
        vals[IT2N_CH_T + k] = ((it2n_val)t * IT2N_MEMB_ONE + IT2N_REGMAP_MEMB_SCALE / 2) / IT2N_REGMAP_MEMB_SCALE;
    }
#undef UP
    rc = models_put_fine(md, i, j, fp, vals, true, &err);
    if (rc)
        return refused_err(md, &err);
    *persisted = 1; /* a failure below: the caller's transaction undoes the point */
    if (models_set_upload(md, v))
        return refused(md, MB_MAP_DEVICE_FAILURE, IT2ND_ERR_NOMEM, -1, -1, -1);
    return MB_MAP_OK;
}

static int par_from_f32(float f, it2n_par *out)
{
    if (!(f >= 0.0f && f <= 1.0f)) /* also rejects NaN */
        return -1;
    *out = (it2n_par)llround((double)f * (double)IT2N_PAR_ONE);
    return 0;
}

/* The two views of a query input say the same: after a write of q_u the
 * float q_u_f reads the new u and vice versa (likewise w, and x, y in
 * scaled and float form), each rounded from the value in use. */
static void sync_views(struct mb_map_query *q)
{
    int sat = 0;
    if (q->views_due & 1u) {
        q->regs[QIDX(IT2N_REGMAP_REG_Q_U16)] = it2n_regmap_par_to_u16(q->u);
        q->regs[QIDX(IT2N_REGMAP_REG_Q_W16)] = it2n_regmap_par_to_u16(q->w);
        it2n_regmap_put_f32(&q->regs[QIDX(IT2N_REGMAP_REG_Q_UF)], (float)((double)q->u / (double)IT2N_PAR_ONE),
                            (unsigned)q->uv_order);
        it2n_regmap_put_f32(&q->regs[QIDX(IT2N_REGMAP_REG_Q_WF)], (float)((double)q->w / (double)IT2N_PAR_ONE),
                            (unsigned)q->uv_order);
    }
    if (q->views_due & 2u) {
        it2n_regmap_put_u32(&q->regs[QIDX(IT2N_REGMAP_REG_Q_XS)],
                            (uint32_t)(int32_t)it2n_regmap_q24_to_scaled(q->x, q->xy_scale, INT32_MIN, INT32_MAX, &sat),
                            (unsigned)q->xy_int32_order);
        it2n_regmap_put_u32(&q->regs[QIDX(IT2N_REGMAP_REG_Q_YS)],
                            (uint32_t)(int32_t)it2n_regmap_q24_to_scaled(q->y, q->xy_scale, INT32_MIN, INT32_MAX, &sat),
                            (unsigned)q->xy_int32_order);
        it2n_regmap_put_f32(&q->regs[QIDX(IT2N_REGMAP_REG_Q_XF)], it2n_regmap_q24_to_f32(q->x), (unsigned)q->xy_order);
        it2n_regmap_put_f32(&q->regs[QIDX(IT2N_REGMAP_REG_Q_YF)], it2n_regmap_q24_to_f32(q->y), (unsigned)q->xy_order);
    }
    q->views_due = 0u;
}

static int write_query(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, unsigned addr,
                       unsigned count, const uint16_t *v)
{
    /* The inputs (the fields before `valid`) only: the cached result is
     * not copied twice per query. */
    struct mb_map_query nq;
    unsigned end = addr + count;
    memcpy(&nq, q, offsetof(struct mb_map_query, valid));
    /* Bit a - Q_U16 for every a = (start of a 32-bit input) + 1: a range
     * starting or ending there cuts that value in half (addr and end lie
     * in the query block: its own lookup). */
#define CUT(a) (1u << ((a) + 1u - IT2N_REGMAP_REG_Q_U16))
    const unsigned cut = CUT(IT2N_REGMAP_REG_Q_UF) | CUT(IT2N_REGMAP_REG_Q_WF) | CUT(IT2N_REGMAP_REG_Q_XS) |
                         CUT(IT2N_REGMAP_REG_Q_YS) | CUT(IT2N_REGMAP_REG_Q_XF) | CUT(IT2N_REGMAP_REG_Q_YF);
#undef CUT
    _Static_assert(IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16 < 32, "query block within the cut mask");
    (void)md;
    if (((cut >> (addr - IT2N_REGMAP_REG_Q_U16)) | (cut >> (end - IT2N_REGMAP_REG_Q_U16))) & 1u)
        return MB_MAP_ILLEGAL_VALUE;
    int uv = addr<IT2N_REGMAP_REG_Q_XS, xy = end> IT2N_REGMAP_REG_Q_XS;
    if (uv && xy)
        return MB_MAP_ILLEGAL_VALUE;
    memcpy(&nq.regs[QIDX(addr)], v, count * sizeof *v);
#define IN(a) (addr <= (a) && (a) < end)
    if (uv) {
        if (IN(IT2N_REGMAP_REG_Q_U16)) {
            if (nq.regs[QIDX(IT2N_REGMAP_REG_Q_U16)] > IT2N_REGMAP_MEMB_SCALE)
                return MB_MAP_ILLEGAL_VALUE;
            nq.u = it2n_regmap_par_from_u16(nq.regs[QIDX(IT2N_REGMAP_REG_Q_U16)]);
        } else if (IN(IT2N_REGMAP_REG_Q_UF) &&
                   par_from_f32(it2n_regmap_get_f32(&nq.regs[QIDX(IT2N_REGMAP_REG_Q_UF)], o->word_order), &nq.u)) {
            return MB_MAP_ILLEGAL_VALUE;
        }
        if (IN(IT2N_REGMAP_REG_Q_W16)) {
            if (nq.regs[QIDX(IT2N_REGMAP_REG_Q_W16)] > IT2N_REGMAP_MEMB_SCALE)
                return MB_MAP_ILLEGAL_VALUE;
            nq.w = it2n_regmap_par_from_u16(nq.regs[QIDX(IT2N_REGMAP_REG_Q_W16)]);
        } else if (IN(IT2N_REGMAP_REG_Q_WF) &&
                   par_from_f32(it2n_regmap_get_f32(&nq.regs[QIDX(IT2N_REGMAP_REG_Q_WF)], o->word_order), &nq.w)) {
            return MB_MAP_ILLEGAL_VALUE;
        }
        nq.kind = 1;
    } else {
        if (IN(IT2N_REGMAP_REG_Q_XS))
            nq.x = it2n_regmap_q24_from_scaled((int32_t)get_u32(&nq.regs[QIDX(IT2N_REGMAP_REG_Q_XS)]), o->coord_scale);
        if (IN(IT2N_REGMAP_REG_Q_YS))
            nq.y = it2n_regmap_q24_from_scaled((int32_t)get_u32(&nq.regs[QIDX(IT2N_REGMAP_REG_Q_YS)]), o->coord_scale);
        for (int c = 0; c < 2; c++) {
            unsigned a = c ? IT2N_REGMAP_REG_Q_YF : IT2N_REGMAP_REG_Q_XF;
            if (!IN(a))
                continue;
            float f = it2n_regmap_get_f32(&nq.regs[QIDX(a)], o->word_order);
            if (!isfinite(f) || fabsf(f) > (float)IT2N_COORD_LIMIT)
                return MB_MAP_ILLEGAL_VALUE;
            it2n_val val = (it2n_val)llround((double)f * (double)IT2N_VAL_ONE);
            if (c)
                nq.y = val;
            else
                nq.x = val;
        }
        if (nq.x > (it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE || nq.x < -(it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE ||
            nq.y > (it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE || nq.y < -(it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE)
            return MB_MAP_ILLEGAL_VALUE;
        nq.kind = 2;
    }
#undef IN
    /* the other views when the query block is read (sync_views), as this
     * write's options would have formatted them */
    if (nq.kind == 1) {
        nq.views_due |= 1u;
        nq.uv_order = o->word_order;
    } else {
        nq.views_due |= 2u;
        nq.xy_order = o->word_order;
        nq.xy_int32_order = o->int32_order;
        nq.xy_scale = o->coord_scale;
    }
    /* The inputs back, the cached result invalid; the rest of *q (the
     * coefficient page) is not nq's to give: it was never copied in. */
    memcpy(q, &nq, offsetof(struct mb_map_query, valid));
    q->valid = 0;
    return MB_MAP_OK;
}

int mb_map_write_changes_model(unsigned addr, unsigned count)
{
    return mb_map_block_changes_model(it2n_regmap_find(addr, count));
}

int mb_map_block_changes_model(const it2n_regmap_block *b)
{
    return b && b->access == IT2N_REGMAP_ACCESS_RW && !b->per_conn; /* per connection: query inputs, coefficient page */
}

/* Select a coefficient page: every value within its limit, or 03 and
 * nothing changed. */
static int write_page(struct mb_map_query *q, unsigned addr, unsigned count, const uint16_t *v)
{
    static const unsigned lim[] = {IT2N_REGMAP_FP, IT2N_REGMAP_CH, IT2N_REGMAP_WIN_ROWS};
    for (unsigned k = 0; k < count; k++)
        if (v[k] >= lim[addr - IT2N_REGMAP_REG_PG_FP + k])
            return MB_MAP_ILLEGAL_VALUE;
    memcpy(&q->page[addr - IT2N_REGMAP_REG_PG_FP], v, count * sizeof *v);
    return MB_MAP_OK;
}

int mb_map_write(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, unsigned addr, unsigned count,
                 const uint16_t *vals, int *persisted)
{
    return mb_map_write_in(md, q, o, it2n_regmap_find(addr, count), addr, count, vals, persisted);
}

int mb_map_write_in(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const it2n_regmap_block *b,
                    unsigned addr, unsigned count, const uint16_t *vals, int *persisted)
{
    *persisted = 0;
    if (!b || b->access != IT2N_REGMAP_ACCESS_RW)
        return refused(md, MB_MAP_ILLEGAL_ADDRESS, IT2N_ERR_INVAL, -1, -1, -1);
    switch (b->start) {
    case IT2N_REGMAP_REG_CFG_N: return write_config(md, addr, count, vals, persisted);
    case IT2N_REGMAP_REG_UP_I: return write_upload(md, o, addr, count, vals, persisted);
    case IT2N_REGMAP_REG_Q_U16: {
        int rc = write_query(md, q, o, addr, count, vals);
        return rc ? refused(md, rc, IT2N_ERR_RANGE, -1, -1, -1) : MB_MAP_OK;
    }
    case IT2N_REGMAP_REG_PG_FP: {
        int rc = write_page(q, addr, count, vals);
        return rc ? refused(md, rc, IT2N_ERR_RANGE, -1, -1, -1) : MB_MAP_OK;
    }
    default: return refused(md, MB_MAP_ILLEGAL_ADDRESS, IT2N_ERR_INVAL, -1, -1, -1);
    }
}
