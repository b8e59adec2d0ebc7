/*
 * plc — simulated PLC: a libmodbus client that drives it2nd the way
 * docs/registers.md tells a PLC engineer, and checks every value against
 * the core's own results for the same data.
 *
 *   plc (--tcp HOST:PORT | --rtu DEV) [--unit U] [--order ABCD] [--scale S]
 *       CMD ...
 *   (the model's memberships as the CSV reader stores them, in Q30: what a
 *   Modbus upload, the preload and a link's PUT FINE give)
 *   CMD: verify CSV [STEPS]   FC23 queries on a STEPSxSTEPS grid, results,
 *                             sample grid and control nets vs the core
 *        upload CSV [commit]  configure + upload every point via the map
 *        stream CSV LOG       upload, appending the count of acknowledged
 *                             points to LOG after each reply (crash tests)
 *        exceptions           exception codes, rejected writes change nothing
 *        concurrent N CSV     N connections with interleaved queries
 *        read ADDR COUNT      print registers (FC03)
 *        wait-gen GEN [MS]    wait until generation >= GEN
 *        write ADDR V...      FC16; prints "ok" or "exception N"
 * Exit status 0 on success, 1 on a mismatch (printed), 2 on usage/I/O.
 */
#include <errno.h>
#include <math.h>
#include <modbus.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "it2n.h"
#include "it2n_regmap.h"
#include "simcommon.h"

__extension__ typedef __int128 i128;

static const char *tcp_host, *tcp_port = "1502", *rtu_dev;
static int unit = 1, order = 0, order32 = 0, scale = 100, failures;

#define CHECK(cond, ...)                                                  \
    do {                                                                  \
        if (!(cond)) {                                                    \
            fprintf(stderr, "plc: FAIL %s:%d: ", __FILE__, __LINE__);     \
            fprintf(stderr, __VA_ARGS__);                                 \
            fputc('\n', stderr);                                          \
            if (++failures > 20)                                          \
                exit(1);                                                  \
        }                                                                 \
    } while (0)

static modbus_t *connect_ctx(void)
{
    modbus_t *ctx = rtu_dev ? modbus_new_rtu(rtu_dev, 19200, 'E', 8, 1) : modbus_new_tcp_pi(tcp_host, tcp_port);
    if (!ctx || modbus_set_slave(ctx, unit) || modbus_connect(ctx)) {
        fprintf(stderr, "plc: connect: %s\n", modbus_strerror(errno));
        exit(2);
    }
    modbus_set_response_timeout(ctx, 3, 0);
    return ctx;
}

/* Registers decode with the map library's codec (tests/regmap pins its
 * bytes against golden values); the expected values below are computed
 * independently of the daemon's encoder. */
#define get32(r, ord) it2n_regmap_get_u32((r), (unsigned)(ord))
#define set32(r, v, ord) it2n_regmap_put_u32((r), (v), (unsigned)(ord))
#define f32(r) it2n_regmap_get_f32((r), (unsigned)order)

/* Q24 to float, independently of the library. */
static float q24f(it2n_val v)
{
    return (float)((double)v / 16777216.0);
}

/* Independent scaled rounding (half away from zero) with saturation. */
static long long scaled(it2n_val v, long long s, long long lim)
{
    long double x = (long double)v * s / 16777216.0L;
    long long q = llroundl(x);
    return q > lim ? lim : q < -lim ? -lim : q;
}

static int read_regs(modbus_t *ctx, int addr, int n, uint16_t *out)
{
    int got = 0;
    while (got < n) {
        int c = n - got > 125 ? 125 : n - got;
        if (modbus_read_registers(ctx, addr + got, c, out + got) != c)
            return -1;
        got += c;
    }
    return 0;
}

static void check_point(const uint16_t *rf, const uint16_t *rs, const it2n_point *pt, const it2n_model *m,
                        const char *what)
{
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!it2n_model_has_fp(m, fp))
            continue;
        for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
            float got = f32(&rf[(fp * 6 + ch) * 2]), want = q24f(pt->v[fp][ch]);
            CHECK(got == want, "%s f32 fp %u ch %u: %.9g != %.9g", what, fp, ch, got, want);
        }
        const uint16_t *r = &rs[fp * 9];
        for (unsigned ch = 0; ch < 3; ch++) {
            int32_t got = (int32_t)get32(&r[ch * 2], order32);
            CHECK(got == scaled(pt->v[fp][ch], scale, INT32_MAX), "%s scaled fp %u ch %u: %d", what, fp, ch, got);
        }
        for (unsigned k = 0; k < 3; k++) {
            int16_t got = (int16_t)r[6 + k];
            CHECK(got == scaled(pt->v[fp][3 + k], 10000, 32767), "%s memb fp %u k %u: %d vs %lld", what, fp, k,
                  got, scaled(pt->v[fp][3 + k], 10000, 32767));
        }
    }
    const it2n_val *sums[4] = { pt->sum.upper_min, pt->sum.upper_max, pt->sum.lower_min, pt->sum.lower_max };
    for (int s = 0; s < 4; s++)
        for (int k = 0; k < 3; k++) {
            float got = f32(&rf[(IT2N_REGMAP_REG_SUM_F32 - IT2N_REGMAP_REG_RES_F32) + (s * 3 + k) * 2]);
            CHECK(got == q24f(sums[s][k]), "%s summary %d %d", what, s, k);
            int16_t gs = (int16_t)rs[IT2N_REGMAP_REG_SUM_SCALED - IT2N_REGMAP_REG_RES_SCALED + s * 3 + k];
            CHECK(gs == scaled(sums[s][k], 10000, 32767), "%s summary scaled %d %d", what, s, k);
        }
}

static void solve_local(const char *csv, it2n_model *m)
{
    static it2n_dataset ds;
    it2n_errinfo err;
    sim_load_csv(csv, 0, &ds);
    it2n_model_init(m);
    if (it2n_model_solve(m, &ds, &err) != IT2N_OK) {
        fprintf(stderr, "plc: local solve failed: %s\n", it2n_strerror(err.code));
        exit(2);
    }
}

/* FC23: write (u, w) x10000, read the float results in the same
 * transaction; then FC03 the scaled view on the same connection. */
static void query_uw(modbus_t *ctx, unsigned u4, unsigned w4, uint16_t *rf, uint16_t *rs)
{
    uint16_t in[2] = { (uint16_t)u4, (uint16_t)w4 };
    int n = IT2N_REGMAP_REG_SUM_F32 + 24 - IT2N_REGMAP_REG_RES_F32;
    int rc = modbus_write_and_read_registers(ctx, IT2N_REGMAP_REG_Q_U16, 2, in, IT2N_REGMAP_REG_RES_F32, n, rf);
    CHECK(rc == n, "FC23 query (%u,%u): %s", u4, w4, modbus_strerror(errno));
    CHECK(read_regs(ctx, IT2N_REGMAP_REG_RES_SCALED, IT2N_REGMAP_REG_RESULTS_END - IT2N_REGMAP_REG_RES_SCALED, rs) == 0,
          "read scaled: %s", modbus_strerror(errno));
}

static int cmd_verify(const char *csv, int steps)
{
    static it2n_model m;
    modbus_t *ctx = connect_ctx();
    uint16_t rf[128], rs[128], st[IT2N_REGMAP_REG_STATUS_END];
    int points = 0;
    solve_local(csv, &m);
    CHECK(read_regs(ctx, 0, IT2N_REGMAP_REG_STATUS_END, st) == 0, "status: %s", modbus_strerror(errno));
    CHECK(st[IT2N_REGMAP_REG_STATE] == IT2N_REGMAP_STATE_SOLVED, "state %u", st[IT2N_REGMAP_REG_STATE]);
    CHECK(st[IT2N_REGMAP_REG_N] == m.n && st[IT2N_REGMAP_REG_M] == m.m, "degrees");
    order = st[IT2N_REGMAP_REG_WORD_ORDER];
    order32 = st[IT2N_REGMAP_REG_INT32_ORDER];
    scale = st[IT2N_REGMAP_REG_COORD_SCALE];
    for (int a = 0; a < steps; a++)
        for (int b = 0; b < steps; b++) {
            unsigned u4 = (unsigned)(a * 10000 / (steps - 1)), w4 = (unsigned)(b * 10000 / (steps - 1));
            it2n_point pt;
            it2n_par u = (it2n_par)(((i128)u4 * IT2N_PAR_ONE + 5000) / 10000);
            it2n_par w = (it2n_par)(((i128)w4 * IT2N_PAR_ONE + 5000) / 10000);
            char what[64];
            it2n_eval(&m, u, w, &pt, NULL);
            query_uw(ctx, u4, w4, rf, rs);
            snprintf(what, sizeof what, "(u,w)=(%u,%u)e-4", u4, w4);
            check_point(rf, rs, &pt, &m, what);
            points++;
        }
    /* Sample grid block. */
    unsigned rows = st[IT2N_REGMAP_REG_GRID_ROWS], cols = st[IT2N_REGMAP_REG_GRID_COLS];
    static uint16_t grid[3 * 256];
    CHECK(read_regs(ctx, IT2N_REGMAP_REG_GRID, (int)(rows * cols * 3), grid) == 0, "grid read");
    for (unsigned r = 0; r < rows; r++)
        for (unsigned c = 0; c < cols; c++) {
            it2n_point pt;
            it2n_par u = (it2n_par)(((i128)r * IT2N_PAR_ONE) / (rows - 1));
            it2n_par w = (it2n_par)(((i128)c * IT2N_PAR_ONE) / (cols - 1));
            it2n_eval(&m, u, w, &pt, NULL);
            for (int k = 0; k < 3; k++) {
                long long want = scaled(pt.v[IT2N_FP_D][3 + k], 10000, 32767);
                int16_t got = (int16_t)grid[(r * cols + c) * 3 + (unsigned)k];
                /* 1 count of slack (it2n_sample once reused row work; it is now
                 * bit-identical to it2n_eval). */
                CHECK(llabs(got - want) <= 1, "grid (%u,%u) k %d: %d vs %lld", r, c, k, got, want);
            }
        }
    /* Float32 view of the same grid. */
    static uint16_t gridf[6 * 256];
    CHECK(read_regs(ctx, IT2N_REGMAP_REG_GRID_F32, (int)(rows * cols * 6), gridf) == 0, "grid f32 read");
    for (unsigned r = 0; r < rows; r++)
        for (unsigned c = 0; c < cols; c++) {
            it2n_point pt;
            it2n_eval(&m, (it2n_par)(((i128)r * IT2N_PAR_ONE) / (rows - 1)),
                      (it2n_par)(((i128)c * IT2N_PAR_ONE) / (cols - 1)), &pt, NULL);
            for (unsigned k = 0; k < 3; k++) {
                float got = f32(&gridf[((r * cols + c) * 3 + k) * 2]), want = q24f(pt.v[IT2N_FP_D][3 + k]);
                CHECK(fabsf(got - want) <= 1e-6f, "grid f32 (%u,%u) k %u: %.9g vs %.9g", r, c, k, got, want);
            }
        }
    /* Control nets, footprint by footprint. */
    static uint16_t net[IT2N_REGMAP_REG_CTRL_END - IT2N_REGMAP_REG_CTRL];
    CHECK(read_regs(ctx, IT2N_REGMAP_REG_CTRL, (int)(IT2N_REGMAP_REG_CTRL_END - IT2N_REGMAP_REG_CTRL), net) == 0, "ctrl read");
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
        for (unsigned i = 0; i <= m.n; i++)
            for (unsigned j = 0; j <= m.m; j++)
                for (unsigned ch = 0; ch < 6; ch++) {
                    if (!it2n_model_has_fp(&m, fp))
                        continue;
                    float got = f32(&net[((((fp * 8 + i) * 8 + j) * 6) + ch) * 2]);
                    CHECK(got == q24f(it2n_model_ctrl(&m, i, j, fp, ch)), "ctrl fp %u (%u,%u) ch %u", fp, i, j, ch);
                }
    modbus_close(ctx);
    modbus_free(ctx);
    printf("plc: verify %s: %d queries, %ux%u grid, control nets: %s\n", csv, points, rows, cols,
           failures ? "FAIL" : "ok");
    return failures ? 1 : 0;
}

/* i32 in the order the daemon says it uses (status int32_word_order). */
static void put_i32(uint16_t *r, int32_t v)
{
    set32(r, (uint32_t)v, order32);
}

static int cmd_upload(const char *csv, int commit, const char *logpath)
{
    FILE *log = logpath ? fopen(logpath, "w") : NULL;
    static it2n_dataset ds;
    modbus_t *ctx = connect_ctx();
    uint16_t cfg[3], st[IT2N_REGMAP_REG_STATUS_END];
    int sent = 0;
    sim_load_csv(csv, 0, &ds);
    CHECK(read_regs(ctx, 0, IT2N_REGMAP_REG_STATUS_END, st) == 0, "status");
    scale = st[IT2N_REGMAP_REG_COORD_SCALE];
    order32 = st[IT2N_REGMAP_REG_INT32_ORDER];
    cfg[0] = ds.n;
    cfg[1] = ds.m;
    cfg[2] = ds.flags;
    CHECK(modbus_write_registers(ctx, IT2N_REGMAP_REG_CFG_N, 3, cfg) == 3, "configure: %s", modbus_strerror(errno));
    for (unsigned i = 0; i <= ds.n; i++)
        for (unsigned j = 0; j <= ds.m; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                uint16_t r[12];
                if (!(ds.present[i][j] & (1u << fp)))
                    continue;
                r[0] = (uint16_t)i;
                r[1] = (uint16_t)j;
                r[2] = (uint16_t)fp;
                for (int c = 0; c < 3; c++)
                    put_i32(&r[3 + 2 * c], (int32_t)scaled(it2n_dataset_value(&ds, i, j, fp, c), scale, INT32_MAX));
                for (int k = 0; k < 3; k++)
                    r[9 + k] = (uint16_t)scaled(it2n_dataset_value(&ds, i, j, fp, 3 + k), 10000, 10000);
                int rc = modbus_write_registers(ctx, IT2N_REGMAP_REG_UP_I, 12, r);
                if (log && rc != 12) { /* daemon killed under us: stop */
                    fclose(log);
                    printf("plc: upload stopped after %d acknowledged points\n", sent);
                    return 0;
                }
                CHECK(rc == 12, "upload (%u,%u,%u): %s", i, j, fp, modbus_strerror(errno));
                sent++;
                if (log) {
                    fprintf(log, "%d\n", sent);
                    fflush(log);
                }
            }
    if (commit) {
        uint16_t one = IT2N_REGMAP_CMD_COMMIT;
        CHECK(modbus_write_register(ctx, IT2N_REGMAP_REG_COMMAND, one) == 1, "commit: %s", modbus_strerror(errno));
    }
    CHECK(read_regs(ctx, 0, IT2N_REGMAP_REG_STATUS_END, st) == 0, "status");
    if (log)
        fclose(log);
    printf("plc: upload %s: %d points, state %u, generation %u\n", csv, sent, st[IT2N_REGMAP_REG_STATE],
           (unsigned)get32(&st[IT2N_REGMAP_REG_GENERATION], order32));
    modbus_close(ctx);
    modbus_free(ctx);
    return failures ? 1 : 0;
}

/* Raw request, returns the exception code (0 = normal reply, -1 = none). */
static int raw(modbus_t *ctx, const uint8_t *pdu, int len)
{
    uint8_t req[260], rsp[MODBUS_MAX_ADU_LENGTH];
    req[0] = (uint8_t)unit;
    memcpy(req + 1, pdu, (size_t)len);
    if (modbus_send_raw_request(ctx, req, len + 1) < 0)
        return -1;
    int rc = modbus_receive_confirmation(ctx, rsp);
    if (rc < 0)
        return -1;
    int hl = modbus_get_header_length(ctx);
    return (rsp[hl] & 0x80) ? rsp[hl + 1] : 0;
}

static int cmd_exceptions(void)
{
    modbus_t *ctx = connect_ctx();
    uint16_t before[IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16], after[IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16];
    uint16_t st0[IT2N_REGMAP_REG_STATUS_END], st1[IT2N_REGMAP_REG_STATUS_END], cfg0[4], cfg1[4];
    uint16_t good[2] = { 2500, 7500 };
    CHECK(modbus_write_registers(ctx, IT2N_REGMAP_REG_Q_U16, 2, good) == 2, "query write");
    read_regs(ctx, IT2N_REGMAP_REG_Q_U16, IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16, before);
    read_regs(ctx, 0, IT2N_REGMAP_REG_STATUS_END, st0);
    read_regs(ctx, IT2N_REGMAP_REG_CFG_N, 4, cfg0);
    struct {
        const char *what;
        uint8_t pdu[32];
        int len, code;
    } t[] = {
        { "read gap after configuration", { 3, 0, IT2N_REGMAP_REG_CONFIG_END, 0, 1 }, 5, 2 },
        { "read past end", { 3, 0x1D, 0x00, 0, 1 }, 5, 2 },
        { "read spans blocks", { 3, 0, 24, 0, 10 }, 5, 2 },
        { "FC04 count 0", { 4, 0, 0, 0, 0 }, 5, 3 },
        { "FC04 count 126", { 4, 0, 0, 0, 126 }, 5, 3 },
        { "FC05 unsupported", { 5, 0, 0, 0xFF, 0 }, 5, 1 },
        { "write read-only status", { 6, 0, 1, 0, 1 }, 5, 2 },
        { "u > 1", { 6, 0, 64, 0x27, 0x11 }, 5, 3 },
        { "half f32 u", { 6, 0, 66, 0, 0 }, 5, 3 },
        { "f32 u = 2.0", { 16, 0, 66, 0, 2, 4, 0x40, 0, 0, 0 }, 10, 3 },
        { "mix uv and xy", { 16, 0, 68, 0, 4, 8, 0, 0, 0, 0, 0, 0, 0, 0 }, 14, 3 },
        { "degree 9", { 6, 0, 32, 0, 9 }, 5, 3 },
        { "bad flags", { 6, 0, 34, 0, 8 }, 5, 3 },
        { "command 7", { 6, 0, 35, 0, 7 }, 5, 3 },
        { "partial upload", { 16, 0, 40, 0, 2, 4, 0, 0, 0, 0 }, 10, 3 },
        { "upload T > 1", { 16, 0, 40, 0, 12, 24, 0, 0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                            0x27, 0x11, 0, 0, 0, 0 }, 30, 3 },
        { "upload i > n", { 16, 0, 40, 0, 12, 24, 0, 9, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                            0, 0, 0, 0, 0, 0 }, 30, 3 },
        { "FC16 byte count wrong", { 16, 0, 64, 0, 1, 4, 0, 1, 0, 1 }, 10, 3 },
        { "FC23 read outside map", { 23, 0, IT2N_REGMAP_REG_CONFIG_END, 0, 1, 0, 64, 0, 1, 2, 0, 1 }, 12, 2 },
    };
    for (size_t k = 0; k < sizeof t / sizeof t[0]; k++) {
        int code = raw(ctx, t[k].pdu, t[k].len);
        CHECK(code == t[k].code, "%s: exception %d, want %d", t[k].what, code, t[k].code);
    }
    read_regs(ctx, IT2N_REGMAP_REG_Q_U16, IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16, after);
    read_regs(ctx, 0, IT2N_REGMAP_REG_STATUS_END, st1);
    read_regs(ctx, IT2N_REGMAP_REG_CFG_N, 4, cfg1);
    CHECK(!memcmp(before, after, sizeof before), "rejected query writes changed the query");
    CHECK(!memcmp(cfg0, cfg1, sizeof cfg0), "rejected config writes changed the configuration");
    CHECK(!memcmp(&st0[IT2N_REGMAP_REG_STATE], &st1[IT2N_REGMAP_REG_STATE], (IT2N_REGMAP_REG_LAST_ERR - IT2N_REGMAP_REG_STATE) * 2),
          "rejected writes changed the model state / generation");
    modbus_close(ctx);
    modbus_free(ctx);
    /* Unknown unit id on TCP: exception 0B. */
    if (!rtu_dev) {
        int saved = unit;
        unit = 200;
        ctx = connect_ctx();
        uint8_t pdu[] = { 3, 0, 0, 0, 1 };
        CHECK(raw(ctx, pdu, 5) == 0x0B, "unknown unit: want 0B");
        modbus_close(ctx);
        modbus_free(ctx);
        unit = saved;
    }
    printf("plc: exceptions: %s\n", failures ? "FAIL" : "ok");
    return failures ? 1 : 0;
}

/* N connections, each with its own (u, w), writes and reads interleaved:
 * every connection must read back its own answer. */
static int cmd_concurrent(int n, const char *csv)
{
    static it2n_model m;
    modbus_t *ctx[64];
    uint16_t rf[128], rs[128];
    if (n < 1 || n > 64)
        return 2;
    solve_local(csv, &m);
    for (int k = 0; k < n; k++)
        ctx[k] = connect_ctx();
    for (int round = 0; round < 5; round++) {
        for (int k = 0; k < n; k++) {
            uint16_t in[2] = { (uint16_t)((k * 997 + round * 131) % 10001), (uint16_t)((k * 389 + round * 733) % 10001) };
            CHECK(modbus_write_registers(ctx[k], IT2N_REGMAP_REG_Q_U16, 2, in) == 2, "write %d", k);
        }
        for (int k = n - 1; k >= 0; k--) {
            unsigned u4 = (unsigned)((k * 997 + round * 131) % 10001), w4 = (unsigned)((k * 389 + round * 733) % 10001);
            it2n_point pt;
            char what[64];
            CHECK(read_regs(ctx[k], IT2N_REGMAP_REG_RES_F32, IT2N_REGMAP_REG_SUM_F32 + 24 - IT2N_REGMAP_REG_RES_F32, rf) == 0, "read");
            CHECK(read_regs(ctx[k], IT2N_REGMAP_REG_RES_SCALED, IT2N_REGMAP_REG_RESULTS_END - IT2N_REGMAP_REG_RES_SCALED, rs) == 0, "read");
            it2n_eval(&m, (it2n_par)(((i128)u4 * IT2N_PAR_ONE + 5000) / 10000),
                      (it2n_par)(((i128)w4 * IT2N_PAR_ONE + 5000) / 10000), &pt, NULL);
            snprintf(what, sizeof what, "conn %d round %d", k, round);
            check_point(rf, rs, &pt, &m, what);
        }
    }
    for (int k = 0; k < n; k++) {
        modbus_close(ctx[k]);
        modbus_free(ctx[k]);
    }
    printf("plc: concurrent %d connections: %s\n", n, failures ? "FAIL" : "ok");
    return failures ? 1 : 0;
}

static int cmd_read(int addr, int count)
{
    modbus_t *ctx = connect_ctx();
    uint16_t r[125];
    if (count < 1 || count > 125 || modbus_read_registers(ctx, addr, count, r) != count) {
        fprintf(stderr, "plc: read: %s\n", modbus_strerror(errno));
        return 1;
    }
    for (int k = 0; k < count; k++)
        printf("%u%c", r[k], k + 1 == count ? '\n' : ' ');
    modbus_close(ctx);
    modbus_free(ctx);
    return 0;
}

/* FC16 write; exit 0 when answered OK, 3 (and the exception code) when
 * the daemon answered with an exception, 2 on I/O errors. */
static int cmd_write(int addr, char **v, int count)
{
    modbus_t *ctx = connect_ctx();
    uint16_t r[123];
    int rc;
    if (count < 1 || count > 123)
        return 2;
    for (int k = 0; k < count; k++)
        r[k] = (uint16_t)strtol(v[k], NULL, 0);
    rc = modbus_write_registers(ctx, addr, count, r);
    if (rc == count) {
        printf("ok\n");
        rc = 0;
    } else if (errno > MODBUS_ENOBASE && errno < MODBUS_ENOBASE + 20) {
        printf("exception %d\n", errno - MODBUS_ENOBASE);
        rc = 3;
    } else {
        fprintf(stderr, "plc: write: %s\n", modbus_strerror(errno));
        rc = 2;
    }
    modbus_close(ctx);
    modbus_free(ctx);
    return rc;
}

static int cmd_wait_gen(unsigned long gen, int ms)
{
    for (int t = 0; t <= ms; t += 50) {
        modbus_t *ctx = connect_ctx();
        uint16_t r[IT2N_REGMAP_REG_STATUS_END];
        int ok = modbus_read_registers(ctx, 0, IT2N_REGMAP_REG_STATUS_END, r) == IT2N_REGMAP_REG_STATUS_END;
        order32 = ok ? r[IT2N_REGMAP_REG_INT32_ORDER] : 0;
        modbus_close(ctx);
        modbus_free(ctx);
        if (ok && get32(&r[IT2N_REGMAP_REG_GENERATION], order32) >= gen)
            return 0;
        usleep(50000);
    }
    fprintf(stderr, "plc: generation %lu not reached\n", gen);
    return 1;
}

int main(int argc, char **argv)
{
    int k = 1;
    static char hostbuf[128];
    for (; k < argc && argv[k][0] == '-'; k += 2) {
        if (k + 1 >= argc)
            return 2;
        if (!strcmp(argv[k], "--tcp")) {
            snprintf(hostbuf, sizeof hostbuf, "%s", argv[k + 1]);
            char *c = strrchr(hostbuf, ':');
            if (!c)
                return 2;
            *c = 0;
            tcp_host = hostbuf;
            tcp_port = c + 1;
        } else if (!strcmp(argv[k], "--rtu")) {
            rtu_dev = argv[k + 1];
        } else if (!strcmp(argv[k], "--unit")) {
            unit = atoi(argv[k + 1]);
        } else {
            return 2;
        }
    }
    if (!tcp_host && !rtu_dev)
        tcp_host = "127.0.0.1";
    if (k >= argc)
        return 2;
    const char *cmd = argv[k++];
    if (!strcmp(cmd, "verify") && k < argc) {
        int steps = k + 1 < argc ? atoi(argv[k + 1]) : 5;
        if (steps < 2 || steps > 100) { /* parameters are a/(steps-1) */
            fprintf(stderr, "plc: verify STEPS must be within 2..100\n");
            return 2;
        }
        return cmd_verify(argv[k], steps);
    }
    if (!strcmp(cmd, "upload") && k < argc)
        return cmd_upload(argv[k], k + 1 < argc && !strcmp(argv[k + 1], "commit"), NULL);
    if (!strcmp(cmd, "stream") && k + 1 < argc)
        return cmd_upload(argv[k], 0, argv[k + 1]);
    if (!strcmp(cmd, "exceptions"))
        return cmd_exceptions();
    if (!strcmp(cmd, "concurrent") && k + 1 < argc)
        return cmd_concurrent(atoi(argv[k]), argv[k + 1]);
    if (!strcmp(cmd, "read") && k + 1 < argc)
        return cmd_read(atoi(argv[k]), atoi(argv[k + 1]));
    if (!strcmp(cmd, "write") && k + 1 < argc)
        return cmd_write(atoi(argv[k]), argv + k + 1, argc - k - 1);
    if (!strcmp(cmd, "wait-gen") && k < argc)
        return cmd_wait_gen(strtoul(argv[k], NULL, 0), k + 1 < argc ? atoi(argv[k + 1]) : 5000);
    fprintf(stderr, "plc: unknown command %s\n", cmd);
    return 2;
}
