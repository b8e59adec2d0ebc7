/* test_mb_map — the register map served for a model (the codecs
 * themselves: tests/regmap/test_regmap.c): map semantics against a model
 * solved from the paper data: reads, writes, exceptions, atomicity. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "errs.h"
#include "it2n_regmap.h"
#include "mb_map.h"
#include "models.h"

static struct model *md;
static const struct mb_map_opts opts = { IT2N_REGMAP_WO_ABCD, 100, 5, 5, { 0 }, IT2N_REGMAP_WO_ABCD, 0 };

static int setup(void **st)
{
    (void)st;
    if (models_init(4))
        return -1;
    md = models_add(1, 1, MODEL_BEZIER, 3, 3, 0);
    return md && models_preload_paper(md) == IT2N_OK ? 0 : -1;
}

static int teardown(void **st)
{
    (void)st;
    models_free();
    return 0;
}

static void test_status(void **st)
{
    struct mb_map_query q;
    uint16_t r[IT2N_REGMAP_REG_STATUS_END];
    (void)st;
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_read(md, &q, &opts, 0, IT2N_REGMAP_REG_STATUS_END, r), MB_MAP_OK);
    assert_int_equal(r[IT2N_REGMAP_REG_MAP_VERSION], IT2N_REGMAP_VERSION);
    assert_int_equal(r[IT2N_REGMAP_REG_STATE], IT2N_REGMAP_STATE_SOLVED);
    assert_int_equal(r[IT2N_REGMAP_REG_PRESENT], 112);
    assert_int_equal(r[IT2N_REGMAP_REG_REQUIRED], 112);
    assert_int_equal(r[IT2N_REGMAP_REG_COORD_SCALE], 100);
    assert_int_equal(r[IT2N_REGMAP_REG_KIND], IT2N_REGMAP_KIND_BEZIER);
    assert_int_equal(r[IT2N_REGMAP_REG_NET_ROWS], 4);
    assert_int_equal(r[IT2N_REGMAP_REG_NET_COLS], 4);
    assert_int_equal(r[IT2N_REGMAP_REG_STATUS_RSV], 0);
    /* gaps and block-spanning reads */
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_CONFIG_END, 1, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_COUNTS_END, 1, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_WIN_END, 1, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, 20, 20, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_CTRL_END, 1, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_MAP_END, 1, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_GRID_F32 + 150, 1, r), MB_MAP_ILLEGAL_ADDRESS); /* past 5x5 nodes */
}

static void test_query_uw(void **st)
{
    struct mb_map_query q;
    uint16_t in[2] = { 2500, 5000 }, r[128];
    it2n_point pt;
    int persisted;
    (void)st;
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_U16, 2, in, &persisted), MB_MAP_OK);
    assert_int_equal(persisted, 0);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_RES_F32, 108, r), MB_MAP_OK);
    assert_int_equal(it2n_eval(&md->mdl, IT2N_PAR_ONE / 4, IT2N_PAR_ONE / 2, &pt, NULL), IT2N_OK);
    for (int fp = 0; fp < 7; fp++)
        for (int ch = 0; ch < 6; ch++)
            assert_true(it2n_regmap_get_f32(&r[(fp * 6 + ch) * 2], IT2N_REGMAP_WO_ABCD) ==
                        (float)((double)pt.v[fp][ch] / IT2N_VAL_ONE));
    /* D footprint T in the scaled view */
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_RES_SCALED, 84, r), MB_MAP_OK);
    int sat = 0;
    assert_int_equal((int16_t)r[3 * 9 + 6], it2n_regmap_q24_to_scaled(pt.v[3][3], 10000, -32767, 32767, &sat));
    assert_int_equal(r[IT2N_REGMAP_REG_SAT - IT2N_REGMAP_REG_RES_SCALED + 3], 0);
}

/* Two registers to 32 bits: ABCD, CDAB, BADC, DCBA (as a PLC decodes). */
static uint32_t reg32(const uint16_t *r, int order)
{
    uint16_t a = r[0], b = r[1];
    if (order == IT2N_REGMAP_WO_BADC || order == IT2N_REGMAP_WO_DCBA) {
        a = (uint16_t)(a >> 8 | a << 8);
        b = (uint16_t)(b >> 8 | b << 8);
    }
    return order == IT2N_REGMAP_WO_CDAB || order == IT2N_REGMAP_WO_DCBA ? (uint32_t)b << 16 | a : (uint32_t)a << 16 | b;
}

/* The two views of each query input agree after a write of either, and
 * u32/i32 registers follow int32_order, in each of the four orders. */
static void test_query_views_and_int32_order(void **st)
{
    (void)st;
    for (int wo = 0; wo < 4; wo++) {
        const struct mb_map_opts o = { wo, 100, 5, 5, { 0 }, (wo + 1) % 4, 0 };
        struct mb_map_query q;
        uint16_t in[2], r[IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16], s[IT2N_REGMAP_REG_STATUS_END];
        int persisted;
        memset(&q, 0, sizeof q);
        /* q_u_f = 0.123456: q_u reads 1235, q_u_f the float as written */
        it2n_regmap_put_f32(in, 0.123456f, wo);
        assert_int_equal(mb_map_write(md, &q, &o, IT2N_REGMAP_REG_Q_UF, 2, in, &persisted), MB_MAP_OK);
        assert_int_equal(mb_map_read(md, &q, &o, IT2N_REGMAP_REG_Q_U16, 14, r), MB_MAP_OK);
        assert_int_equal(r[0], 1235);
        assert_true(it2n_regmap_get_f32(&r[IT2N_REGMAP_REG_Q_UF - IT2N_REGMAP_REG_Q_U16], wo) == 0.123456f);
        /* q_w = 7500: q_w_f reads 0.75, u unchanged */
        in[0] = 7500;
        assert_int_equal(mb_map_write(md, &q, &o, IT2N_REGMAP_REG_Q_W16, 1, in, &persisted), MB_MAP_OK);
        assert_int_equal(mb_map_read(md, &q, &o, IT2N_REGMAP_REG_Q_U16, 14, r), MB_MAP_OK);
        assert_true(it2n_regmap_get_f32(&r[IT2N_REGMAP_REG_Q_WF - IT2N_REGMAP_REG_Q_U16], wo) == 0.75f);
        assert_int_equal(r[0], 1235);
        /* q_x_f = -17.5: q_x reads -1750 as i32 in int32_order */
        it2n_regmap_put_f32(in, -17.5f, wo);
        assert_int_equal(mb_map_write(md, &q, &o, IT2N_REGMAP_REG_Q_XF, 2, in, &persisted), MB_MAP_OK);
        assert_int_equal(mb_map_read(md, &q, &o, IT2N_REGMAP_REG_Q_U16, 14, r), MB_MAP_OK);
        assert_int_equal((int32_t)reg32(&r[IT2N_REGMAP_REG_Q_XS - IT2N_REGMAP_REG_Q_U16], o.int32_order), -1750);
        /* generation (u32) in int32_order, the order said in status 27 */
        assert_int_equal(mb_map_read(md, &q, &o, 0, IT2N_REGMAP_REG_STATUS_END, s), MB_MAP_OK);
        assert_int_equal(s[IT2N_REGMAP_REG_WORD_ORDER], wo);
        assert_int_equal(s[IT2N_REGMAP_REG_INT32_ORDER], (wo + 1) % 4);
        assert_int_equal(reg32(&s[IT2N_REGMAP_REG_GENERATION], o.int32_order), md->gen);
    }
}

/* The views a write makes (formatted when the block is read) are those of
 * that write: a (u, w) write then an (x, y) write, both read afterwards,
 * in the word orders and scale the writes had, not the reader's (a
 * reload between them changes the options). */
static void test_query_views_of_the_write(void **st)
{
    const struct mb_map_opts w1 = { IT2N_REGMAP_WO_ABCD, 100, 5, 5, { 0 }, IT2N_REGMAP_WO_CDAB, 0 };
    const struct mb_map_opts w2 = { IT2N_REGMAP_WO_DCBA, 10, 5, 5, { 0 }, IT2N_REGMAP_WO_BADC, 0 };
    const struct mb_map_opts rd = { IT2N_REGMAP_WO_BADC, 1000, 5, 5, { 0 }, IT2N_REGMAP_WO_ABCD, 0 };
    struct mb_map_query q;
    uint16_t in[2], r[IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16];
    int persisted;
    (void)st;
    memset(&q, 0, sizeof q);
    in[0] = 2500;
    in[1] = 7500;
    assert_int_equal(mb_map_write(md, &q, &w1, IT2N_REGMAP_REG_Q_U16, 2, in, &persisted), MB_MAP_OK);
    it2n_regmap_put_f32(in, -17.5f, w2.word_order);
    assert_int_equal(mb_map_write(md, &q, &w2, IT2N_REGMAP_REG_Q_XF, 2, in, &persisted), MB_MAP_OK);
    assert_int_equal(mb_map_read(md, &q, &rd, IT2N_REGMAP_REG_Q_U16, 14, r), MB_MAP_OK);
    assert_true(it2n_regmap_get_f32(&r[IT2N_REGMAP_REG_Q_UF - IT2N_REGMAP_REG_Q_U16], w1.word_order) == 0.25f);
    assert_true(it2n_regmap_get_f32(&r[IT2N_REGMAP_REG_Q_WF - IT2N_REGMAP_REG_Q_U16], w1.word_order) == 0.75f);
    assert_int_equal((int32_t)reg32(&r[IT2N_REGMAP_REG_Q_XS - IT2N_REGMAP_REG_Q_U16], w2.int32_order), -175);
    assert_true(it2n_regmap_get_f32(&r[IT2N_REGMAP_REG_Q_XF - IT2N_REGMAP_REG_Q_U16], w2.word_order) == -17.5f);
    assert_int_equal(r[0], 2500);
    assert_int_equal(r[1], 7500);
}

/* A query write changes the query inputs only: the coefficient page the
 * connection selected, and the result of a later read, stay its own. */
static void test_query_write_keeps_page(void **st)
{
    struct mb_map_query q;
    uint16_t page[3] = { 2, 3, 1 }, in[2] = { 2500, 5000 }, r[3];
    int persisted;
    (void)st;
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_PG_FP, 3, page, &persisted), MB_MAP_OK);
    for (int k = 0; k < 3; k++) {
        in[0] = (uint16_t)(1000 + 3000 * k);
        assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_U16, 2, in, &persisted), MB_MAP_OK);
        assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_PG_FP, 3, r), MB_MAP_OK);
        assert_memory_equal(r, page, sizeof page);
    }
}

/* Every range of the query block: refused (03, nothing changed) exactly
 * when it cuts a 32-bit input in half at either end, or spans both the
 * (u, w) and the (x, y) inputs; all-zero values are valid otherwise. */
static void test_query_ranges(void **st)
{
    static const unsigned wide[] = { IT2N_REGMAP_REG_Q_UF, IT2N_REGMAP_REG_Q_WF, IT2N_REGMAP_REG_Q_XS,
                                     IT2N_REGMAP_REG_Q_YS, IT2N_REGMAP_REG_Q_XF, IT2N_REGMAP_REG_Q_YF };
    uint16_t zero[IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16] = { 0 };
    unsigned tried = 0, refused = 0;
    (void)st;
    for (unsigned a = IT2N_REGMAP_REG_Q_U16; a < IT2N_REGMAP_REG_QUERY_END; a++)
        for (unsigned end = a + 1; end <= IT2N_REGMAP_REG_QUERY_END; end++) {
            struct mb_map_query q, q0;
            int persisted, cut = 0;
            for (unsigned k = 0; k < sizeof wide / sizeof wide[0]; k++)
                cut |= a == wide[k] + 1 || end == wide[k] + 1;
            int bad = cut || (a < IT2N_REGMAP_REG_Q_XS && end > IT2N_REGMAP_REG_Q_XS);
            memset(&q, 0, sizeof q);
            q0 = q;
            int rc = mb_map_write(md, &q, &opts, a, end - a, zero, &persisted);
            if (rc != (bad ? MB_MAP_ILLEGAL_VALUE : MB_MAP_OK))
                fail_msg("query registers %u..%u: exception %d, expected %d", a, end - 1, rc,
                         bad ? MB_MAP_ILLEGAL_VALUE : MB_MAP_OK);
            if (bad)
                assert_memory_equal(&q, &q0, sizeof q);
            tried++;
            refused += bad != 0;
        }
    assert_int_equal(tried, 105);
    assert_true(refused > 0 && refused < tried);
}

static void test_rejected_writes_change_nothing(void **st)
{
    struct mb_map_query q, q0;
    uint16_t good[2] = { 1000, 2000 }, bad[2] = { 1000, 10001 };
    int persisted;
    uint32_t gen = md->gen;
    (void)st;
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_U16, 2, good, &persisted), MB_MAP_OK);
    q0 = q;
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_U16, 2, bad, &persisted), MB_MAP_ILLEGAL_VALUE);
    assert_memory_equal(&q, &q0, sizeof q);
    /* half a float */
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_UF + 1, 1, good, &persisted), MB_MAP_ILLEGAL_VALUE);
    /* f32 u = 1.5 */
    uint16_t f[2];
    it2n_regmap_put_f32(f, 1.5f, IT2N_REGMAP_WO_ABCD);
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_UF, 2, f, &persisted), MB_MAP_ILLEGAL_VALUE);
    assert_memory_equal(&q, &q0, sizeof q);
    /* degree 0 and 8, flags bit 3 */
    uint16_t cfg[3] = { 0, 3, 0 };
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_CFG_N, 3, cfg, &persisted), MB_MAP_ILLEGAL_VALUE);
    cfg[0] = 8;
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_CFG_N, 3, cfg, &persisted), MB_MAP_ILLEGAL_VALUE);
    cfg[0] = 3;
    cfg[2] = 8;
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_CFG_N, 3, cfg, &persisted), MB_MAP_ILLEGAL_VALUE);
    /* upload that breaks footprint nesting: solve (update) fails -> 04 */
    uint16_t up[12] = { 0, 0, IT2N_FP_LL, 0, 1000, 0, 0, 0, 0, 5000, 5000, 5000 }; /* x = 10 > D's -17 */
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_UP_I, 12, up, &persisted), MB_MAP_DEVICE_FAILURE);
    assert_int_equal(persisted, 0);
    /* read-only block */
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_STATE, 1, good, &persisted), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(md->gen, gen);
    assert_int_equal(md->state, IT2N_REGMAP_STATE_SOLVED);
}

static void test_incomplete_is_busy(void **st)
{
    struct model *m2 = models_add(2, 2, MODEL_BEZIER, 2, 2, IT2N_F_TYPE1);
    struct mb_map_query q;
    uint16_t r[8], one = IT2N_REGMAP_CMD_COMMIT;
    int persisted;
    (void)st;
    assert_non_null(m2);
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_read(m2, &q, &opts, IT2N_REGMAP_REG_RES_F32, 2, r), MB_MAP_BUSY);
    assert_int_equal(mb_map_read(m2, &q, &opts, IT2N_REGMAP_REG_GRID, 3, r), MB_MAP_BUSY);
    assert_int_equal(mb_map_read(m2, &q, &opts, IT2N_REGMAP_REG_CTRL, 2, r), MB_MAP_BUSY);
    assert_int_equal(mb_map_write(m2, &q, &opts, IT2N_REGMAP_REG_COMMAND, 1, &one, &persisted), MB_MAP_BUSY);
    /* grid beyond rows*cols nodes is outside the map */
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_GRID + 75, 1, r), MB_MAP_ILLEGAL_ADDRESS);
    assert_int_equal(mb_map_read(md, &q, &opts, IT2N_REGMAP_REG_GRID + 72, 3, r), MB_MAP_OK);
}

/* Interpolants overshoot between data points: the x10000 grid view clamps
 * those values, and status grid_saturated counts exactly the clamped ones
 * (checked against the raw float32 view of the same grid). */
static void test_grid_saturation_flag(void **st)
{
    /* A 7x7 checkerboard oscillates far outside [0, 1] at u, w = k/14. */
    struct model *m3 = models_add(3, 3, MODEL_BEZIER, 7, 7, IT2N_F_TYPE1);
    const struct mb_map_opts g15 = { IT2N_REGMAP_WO_ABCD, 100, 15, 15, { 0 }, IT2N_REGMAP_WO_ABCD, 0 };
    static uint16_t grid[15 * 15 * 3], gf[15 * 15 * 6];
    uint16_t r[IT2N_REGMAP_REG_STATUS_END];
    it2n_errinfo err;
    struct mb_map_query q;
    unsigned clamped = 0, raw_out = 0;
    (void)st;
    assert_non_null(m3);
    for (unsigned i = 0; i <= 7; i++)
        for (unsigned j = 0; j <= 7; j++) {
            it2n_val v[IT2N_CH_COUNT] = { (it2n_val)i * IT2N_VAL_ONE, (it2n_val)j * IT2N_VAL_ONE, 0,
                                          ((i + j) % 2) ? IT2N_VAL_ONE : 0, IT2N_VAL_ONE / 2,
                                          IT2N_VAL_ONE / 2 };
            assert_int_equal(models_put(m3, i, j, IT2N_FP_D, v, false, &err), IT2N_OK);
        }
    if (m3->state != IT2N_REGMAP_STATE_SOLVED)
        assert_int_equal(models_commit(m3, &err), IT2N_OK);
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_read(m3, &q, &g15, 0, IT2N_REGMAP_REG_STATUS_END, r), MB_MAP_OK);
    /* FC 03 reads at most 125 registers: fetch both views in chunks. */
    for (unsigned k = 0; k < 675; k += 120)
        assert_int_equal(mb_map_read(m3, &q, &g15, IT2N_REGMAP_REG_GRID + k, k + 120 <= 675 ? 120 : 675 - k, grid + k),
                         MB_MAP_OK);
    for (unsigned k = 0; k < 1350; k += 120)
        assert_int_equal(
            mb_map_read(m3, &q, &g15, IT2N_REGMAP_REG_GRID_F32 + k, k + 120 <= 1350 ? 120 : 1350 - k, gf + k), MB_MAP_OK);
    for (unsigned k = 0; k < 675; k++) {
        int16_t v = (int16_t)grid[k];
        uint32_t bits = (uint32_t)gf[2 * k] << 16 | gf[2 * k + 1];
        float f;
        memcpy(&f, &bits, sizeof f);
        clamped += v == 32767 || v == -32767;
        raw_out += f > 3.2767f || f < -3.2767f;
    }
    assert_true(raw_out > 0);
    assert_int_equal(clamped, raw_out);
    assert_int_equal(r[IT2N_REGMAP_REG_GRID_SAT], raw_out);
    /* The paper model stays within range. */
    assert_int_equal(mb_map_read(md, &q, &opts, 0, IT2N_REGMAP_REG_STATUS_END, r), MB_MAP_OK);
    assert_int_equal(r[IT2N_REGMAP_REG_GRID_SAT], 0);
}

/* Every refused write says why in last_error (issue 8 item 11: an upload
 * refused with 03 for T = 1.2 left it 0), and a disk failure is the
 * daemon's code, not the core's IT2N_ERR_STATE ("model not in state"). */
static int journal_fails(void *arg, const struct model_rec *rec)
{
    (void)arg;
    (void)rec;
    return IT2ND_ERR_DEGRADED;
}

static void status_err(int16_t *code, int16_t *i, int16_t *j, int16_t *fp)
{
    struct mb_map_query q;
    uint16_t r[IT2N_REGMAP_REG_STATUS_END];
    memset(&q, 0, sizeof q);
    assert_int_equal(mb_map_read(md, &q, &opts, 0, IT2N_REGMAP_REG_STATUS_END, r), MB_MAP_OK);
    *code = (int16_t)r[IT2N_REGMAP_REG_LAST_ERR];
    *i = (int16_t)r[IT2N_REGMAP_REG_ERR_I];
    *j = (int16_t)r[IT2N_REGMAP_REG_ERR_J];
    *fp = (int16_t)r[IT2N_REGMAP_REG_ERR_FP];
}

static void test_refused_writes_set_last_error(void **st)
{
    struct mb_map_query q;
    int persisted;
    int16_t code, i, j, fp;
    uint32_t gen = md->gen;
    (void)st;
    memset(&q, 0, sizeof q);
    memset(&md->last_err, 0, sizeof md->last_err);
    /* T = 1.2 at (1, 2, D): 03, last_error RANGE at the point */
    uint16_t up[12] = { 1, 2, IT2N_FP_D, 0, 1000, 0, 0, 0, 0, 12000, 5000, 5000 };
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_UP_I, 12, up, &persisted), MB_MAP_ILLEGAL_VALUE);
    status_err(&code, &i, &j, &fp);
    assert_int_equal(code, IT2N_ERR_RANGE);
    assert_int_equal(i, 1);
    assert_int_equal(j, 2);
    assert_int_equal(fp, IT2N_FP_D);
    assert_int_equal(md->last_err.ch, IT2N_CH_T);
    /* index beyond the degree: INVAL */
    up[0] = 9;
    up[9] = 5000;
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_UP_I, 12, up, &persisted), MB_MAP_ILLEGAL_VALUE);
    status_err(&code, &i, &j, &fp);
    assert_int_equal(code, IT2N_ERR_INVAL);
    assert_int_equal(i, 9);
    /* a bad configuration and a query parameter beyond 1 */
    uint16_t cfg[3] = { 0, 3, 0 }, uw[2] = { 10001, 0 };
    memset(&md->last_err, 0, sizeof md->last_err);
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_CFG_N, 3, cfg, &persisted), MB_MAP_ILLEGAL_VALUE);
    status_err(&code, &i, &j, &fp);
    assert_int_equal(code, IT2N_ERR_INVAL);
    memset(&md->last_err, 0, sizeof md->last_err);
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_U16, 2, uw, &persisted), MB_MAP_ILLEGAL_VALUE);
    status_err(&code, &i, &j, &fp);
    assert_int_equal(code, IT2N_ERR_RANGE);
    memset(&md->last_err, 0, sizeof md->last_err);
    mb_map_refused(md, MB_MAP_ILLEGAL_VALUE); /* a malformed write PDU (mb_req) */
    assert_int_equal(md->last_err.code, IT2N_ERR_INVAL);
    /* The WAL refuses (degraded store): 04, the daemon's code, nothing changed. */
    models_set_journal(journal_fails, NULL);
    uint16_t recfg[3] = { 2, 2, 0 };
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_CFG_N, 3, recfg, &persisted), MB_MAP_DEVICE_FAILURE);
    assert_int_equal(persisted, 0);
    status_err(&code, &i, &j, &fp);
    assert_int_equal(code, IT2ND_ERR_DEGRADED);
    assert_int_equal(i, -1);
    assert_int_equal(md->ds.n, 3);
    uint16_t clear[4] = { md->ds.n, md->ds.m, md->ds.flags, IT2N_REGMAP_CMD_CLEAR };
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_CFG_N, 4, clear, &persisted), MB_MAP_DEVICE_FAILURE);
    assert_int_equal(md->last_err.code, IT2ND_ERR_DEGRADED);
    models_set_journal(NULL, NULL);
    models_pass_end(1, NULL, NULL);
    assert_int_equal(md->gen, gen);
    assert_int_equal(md->state, IT2N_REGMAP_STATE_SOLVED);
    memset(&md->last_err, 0, sizeof md->last_err);
}

/* A connection's cached query result is keyed on the model instance and
 * generation. A change that is rolled back (its batch failed) and another
 * change that then reaches the same generation number must not be served
 * from the cache of the first: a rollback gives the model a new instance. */
static void test_query_cache_after_rollback(void **st)
{
    struct mb_map_query q, fresh;
    uint16_t uw[2] = { 5000, 5000 }, a[2], b[2], c[2];
    const unsigned res_t = IT2N_REGMAP_REG_RES_F32 + (IT2N_FP_D * IT2N_CH_COUNT + IT2N_CH_T) * 2;
    it2n_val v[IT2N_CH_COUNT], orig[IT2N_CH_COUNT];
    it2n_errinfo err;
    int persisted;
    (void)st;
    memset(&q, 0, sizeof q);
    memset(&fresh, 0, sizeof fresh);
    uint32_t gen = md->gen;
    assert_int_equal(mb_map_write(md, &q, &opts, IT2N_REGMAP_REG_Q_U16, 2, uw, &persisted), MB_MAP_OK);
    assert_int_equal(mb_map_write(md, &fresh, &opts, IT2N_REGMAP_REG_Q_U16, 2, uw, &persisted), MB_MAP_OK);
    it2n_dataset_get(&md->ds, 1, 1, IT2N_FP_D, orig);
    memcpy(v, orig, sizeof v);
    v[IT2N_CH_T] += IT2N_VAL_ONE / 10;
    assert_int_equal(models_put(md, 1, 1, IT2N_FP_D, v, true, &err), IT2N_OK);
    assert_int_equal(md->gen, gen + 1);
    assert_int_equal(mb_map_read(md, &q, &opts, res_t, 2, a), MB_MAP_OK); /* cached at gen + 1 */
    models_pass_end(0, NULL, NULL);                                    /* the batch failed */
    assert_int_equal(md->gen, gen);
    v[IT2N_CH_T] = orig[IT2N_CH_T] - IT2N_VAL_ONE / 10;
    assert_int_equal(models_put(md, 1, 1, IT2N_FP_D, v, true, &err), IT2N_OK);
    assert_int_equal(md->gen, gen + 1);                                /* same number, other data */
    assert_int_equal(mb_map_read(md, &q, &opts, res_t, 2, b), MB_MAP_OK);
    assert_int_equal(mb_map_read(md, &fresh, &opts, res_t, 2, c), MB_MAP_OK);
    assert_memory_equal(b, c, sizeof b);
    assert_memory_not_equal(a, b, sizeof a);
    /* Back to the paper data for the tests after this one. */
    assert_int_equal(models_put(md, 1, 1, IT2N_FP_D, orig, true, &err), IT2N_OK);
    models_pass_end(1, NULL, NULL);
    memset(&md->last_err, 0, sizeof md->last_err);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_status),
        cmocka_unit_test(test_query_uw),
        cmocka_unit_test(test_query_views_and_int32_order),
        cmocka_unit_test(test_query_views_of_the_write),
        cmocka_unit_test(test_query_write_keeps_page),
        cmocka_unit_test(test_query_ranges),
        cmocka_unit_test(test_rejected_writes_change_nothing),
        cmocka_unit_test(test_incomplete_is_busy),
        cmocka_unit_test(test_grid_saturation_flag),
        cmocka_unit_test(test_refused_writes_set_last_error),
        cmocka_unit_test(test_query_cache_after_rollback),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
