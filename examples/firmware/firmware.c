/*
 * it2n instrument firmware, emulated: qemu mps2-an385 (Cortex-M3).
 *
 * Synthesises a measured grid (examples/instrument/synth.c: seven nested
 * footprints, z, T/I/F memberships), solves it locally with the core,
 * uploads it over CMSDK UART0 with the serial protocol v1.2 through the
 * instrument API of protocol/it2n_inst.h (HELLO, CONFIGURE, batched PUTs,
 * COMMIT, sync; docs/instrument.md), then QUERYs the peer at a set of (u, w) and
 * checks each QUERY_RESULT bit for bit against its own evaluation. Its own
 * evaluations at the Modbus points are printed over semihosting as
 *   EVAL <u x10000> <w x10000> <out_of_range> <42 values> <12 summary>
 * (raw Q24 integers), for tests/firmware/fw_e2e.sh to compare with Modbus.
 * No heap; everything lives in .bss.
 */
#include <string.h>

#include "board.h"
#include "fw_print.h"
#include "semihost.h"
#include "it2n_inst.h"
#include "synth.h"

#ifndef FW_N
#define FW_N 5
#endif
#ifndef FW_M
#define FW_M 4
#endif
#ifndef FW_MODEL
#define FW_MODEL 1
#endif
#ifndef FW_SEED
#define FW_SEED 2026u
#endif
/* FW_REBOOT_TEST (tests/firmware/fw_reboot.sh only): the measurement of
 * this boot comes from the host file fw-seed (semihosting; a new
 * measurement per boot with one image), and the image idles after its
 * checks instead of ending the emulation, so the test can reset it. The
 * protocol side is the same as in the example: nothing differs between
 * boots but the data. */
#define FW_RTO_MS 150u
#define FW_TRIES 40u
#define FW_QUERY_WAIT_MS 10000u

/* (u, w) x10000, as written to the Modbus q_u / q_w registers. */
static const uint16_t fw_points[][2] = {
    {0, 0}, {10000, 10000}, {2500, 5000}, {7000, 3000}, {1234, 8765}, {5000, 5000}, {9999, 1}, {3333, 6667},
};
#define FW_NPOINTS (sizeof fw_points / sizeof fw_points[0])

static it2n_dataset ds;
static it2n_model mdl;
static it2n_inst inst;
static it2n_point local_pt;

/* The peer's QUERY_RESULT. */
static it2n_msg_query_result q_res;

/* ---- output over semihosting: fw_print.h ---- */

static uint32_t fw_seed(void)
{
#ifdef FW_REBOOT_TEST
    char b[16];
    uint32_t v = 0;
    unsigned k;
    if (it2n_sh_read_file("fw-seed", b, sizeof b) > 0) {
        for (k = 0; b[k] >= '0' && b[k] <= '9' && k < 9u; k++)
            v = v * 10u + (uint32_t)(b[k] - '0');
        fw_print_str("SEED ");
        fw_print_u64(v);
        fw_print_flush();
        return v;
    }
#endif
    return FW_SEED;
}

/* ---- the instrument API's callbacks on UART0 ---- */

static int uart_out(void *user, const uint8_t *buf, size_t len)
{
    (void)user;
    uart_write(buf, len);
    return 0;
}

static int uart_in(void *user, uint8_t *buf, size_t len)
{
    (void)user;
    return (int)uart_read(buf, len > 256u ? 256u : len);
}

static uint32_t clock_ms(void *user)
{
    (void)user;
    return board_now_ms();
}

static void idle(void *user)
{
    (void)user;
    board_idle();
}

/* Q32 parameter from x10000, rounded as it2nd does for q_u / q_w. */
static it2n_par par_from_x10000(uint16_t k)
{
    return (it2n_par)((((uint64_t)k << IT2N_PAR_FRAC) + 5000u) / 10000u);
}

static bool same_point(const it2n_point *a, const it2n_msg_query_result *r)
{
    return memcmp(a->v, r->v, sizeof a->v) == 0 && memcmp(&a->sum, &r->sum, sizeof a->sum) == 0 &&
           a->out_of_range == r->out_of_range;
}

static void fail(const char *what, int64_t code)
{
    fw_print_str("FAIL: ");
    fw_print_str(what);
    fw_print_str(" ");
    fw_print_i64(code);
    fw_print_flush();
}

static unsigned resyncs;

/* CONFIGURE, every point of the data set, COMMIT, and wait for the ACKs. */
static int send_model(void)
{
    unsigned i, j, fp;
    int r = it2n_inst_configure(&inst, FW_MODEL, FW_N, FW_M, IT2N_F_Z);
    for (i = 0; r == 0 && i <= ds.n; i++)
        for (j = 0; r == 0 && j <= ds.m; j++)
            for (fp = 0; r == 0 && fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                if (!(ds.present[i][j] & (1u << fp)))
                    continue;
                /* as stored (memberships in Q30): PUT FINE to a v1.3
                 * daemon, so its model is this one bit for bit */
                it2n_dataset_get_fine(&ds, i, j, fp, v);
                r = it2n_inst_put_fine(&inst, FW_MODEL, (uint8_t)i, (uint8_t)j, (uint8_t)fp, v);
            }
    if (r == 0)
        r = it2n_inst_commit(&inst, FW_MODEL);
    if (r == 0)
        r = it2n_inst_sync(&inst);
    return r;
}

/* Upload with the instrument API; a failed attempt (peer absent, retries
 * exhausted) starts over with a fresh sequence, up to three times —
 * points the daemon already holds with the same values are ACKed without
 * effect, so sending them again is safe. */
static int upload(void)
{
    unsigned attempt;
    it2n_inst_cfg cfg;
    int r;
    memset(&cfg, 0, sizeof cfg);
    cfg.write = uart_out;
    cfg.read = uart_in;
    cfg.now_ms = clock_ms;
    cfg.idle = idle;
    /* Protocol v1.2 (cfg.version 0): it2nd hands out the session id in its
     * HELLO, so this board needs no boot counter, TRNG or clock-derived
     * id: every boot may start exactly alike (docs/instrument.md). */
#ifdef FW_V11_HANDSHAKE
    /* tests/firmware/fw_reboot.sh only: the v1.1 handshake as this example
     * did it before 1.2, an id from the clock at start, which repeats on
     * every boot with deterministic timing: the reboot test must fail */
    cfg.version = IT2N_PROTO_VERSION;
    cfg.session_id = board_now_ms() * 2654435761u ^ 0x1F2E3D4Cu;
    cfg.first_seq = (uint16_t)board_now_ms();
#endif
    cfg.rto_ms = FW_RTO_MS;
    cfg.max_tries = (uint8_t)FW_TRIES;
    cfg.timeout_ms = 60000u;
    cfg.node = "it2n-firmware";
    r = it2n_inst_open(&inst, &cfg);
    for (attempt = 0; attempt < 3u; attempt++) {
        if (r == 0)
            r = send_model();
        if (r == 0)
            return 0;
        fail("upload attempt failed, code", r);
        resyncs++;
        r = it2n_inst_resync(&inst, (uint16_t)(inst.link.tx_next + 1000u));
    }
    return -1;
}

/* QUERY, resynchronising the link and asking again when it fails. */
static int query_retry(uint32_t wu, uint32_t ww)
{
    unsigned attempt;
    int r = it2n_inst_query(&inst, FW_MODEL, wu, ww, &q_res);
    for (attempt = 0; r != 0 && attempt < 3u; attempt++) {
        fw_print_str("QUERY failed (");
        fw_print_i64(r);
        fw_print_str("): resynchronising the link; stats rx_delivered ");
        fw_print_u64(inst.link.stats.rx_delivered);
        fw_print_str(" rx_dup ");
        fw_print_u64(inst.link.stats.rx_dup);
        fw_print_str(" rx_buffered ");
        fw_print_u64(inst.link.stats.rx_buffered);
        fw_print_str(" rx_nosync ");
        fw_print_u64(inst.link.stats.rx_nosync);
        fw_print_str(" tx_timeouts ");
        fw_print_u64(inst.link.stats.tx_timeouts);
        fw_print_str(" frames ok ");
        fw_print_u64(inst.link.dec.stats.ok);
        fw_print_str(" crc ");
        fw_print_u64(inst.link.dec.stats.crc);
        fw_print_flush();
        resyncs++;
        if (it2n_inst_resync(&inst, (uint16_t)(inst.link.tx_next + 1000u)) == 0)
            r = it2n_inst_query(&inst, FW_MODEL, wu, ww, &q_res);
    }
    return r;
}

int main(void)
{
    it2n_errinfo err;
    uint32_t t0, t1;
    unsigned k, mismatches = 0;
    int r;

    board_init();
    it2n_sh_write0("it2n firmware: mps2-an385 Cortex-M3, UART0 115200\n");
    r = synth_dataset(&ds, FW_N, FW_M, IT2N_F_Z, fw_seed(), &err);
    if (r != IT2N_OK) {
        fail("synth_dataset", r);
        return 1;
    }
    it2n_model_init(&mdl);
    r = it2n_model_solve(&mdl, &ds, &err);
    if (r != IT2N_OK) {
        fail("local solve", r);
        return 1;
    }
    fw_print_str("local model solved: n ");
    fw_print_u64(FW_N);
    fw_print_str(" m ");
    fw_print_u64(FW_M);
    fw_print_str(" flags z");
    fw_print_flush();

    t0 = board_now_ms();
    if (upload() != 0)
        return 1;
    t1 = board_now_ms();
    fw_print_str("UPLOAD committed ms ");
    fw_print_u64(t1 - t0);
    fw_print_str(" puts ");
    fw_print_u64(inst.puts);
    fw_print_str(" entries ");
    fw_print_u64(inst.entries);
    fw_print_str(" retx ");
    fw_print_u64(inst.link.stats.tx_retx);
    fw_print_str(" rx_overruns ");
    fw_print_u64(uart_rx_overruns());
    fw_print_flush();

    for (k = 0; k < FW_NPOINTS; k++) {
        it2n_par u = par_from_x10000(fw_points[k][0]);
        it2n_par w = par_from_x10000(fw_points[k][1]);
        uint32_t wu = it2n_par_to_wire(u), ww = it2n_par_to_wire(w);

        /* 1. the peer's answer over the link vs the local core at the
         *    same wire parameters */
        r = it2n_eval(&mdl, it2n_par_from_wire(wu), it2n_par_from_wire(ww), &local_pt, &err);
        if (r != IT2N_OK) {
            fail("local eval (wire)", r);
            return 1;
        }
        r = query_retry(wu, ww);
        if (r != 0) {
            fail("QUERY", r);
            return 1;
        }
        if (!same_point(&local_pt, &q_res)) {
            fail("QUERY_RESULT differs from the local evaluation, point", (int64_t)k);
            mismatches++;
        }

        /* 2. the local evaluation at the Modbus parameters, printed */
        r = it2n_eval(&mdl, u, w, &local_pt, &err);
        if (r != IT2N_OK) {
            fail("local eval", r);
            return 1;
        }
        fw_print_eval(fw_points[k][0], fw_points[k][1], &local_pt);
    }
    fw_print_str("QUERY bit-identical ");
    fw_print_u64(FW_NPOINTS - mismatches);
    fw_print_str("/");
    fw_print_u64(FW_NPOINTS);
    fw_print_str(" retx ");
    fw_print_u64(inst.link.stats.tx_retx);
    fw_print_str(" resyncs ");
    fw_print_u64(resyncs);
    fw_print_flush();
    if (mismatches != 0u)
        return 1;
    it2n_sh_write0("PASS firmware\n");
#ifdef FW_REBOOT_TEST
    for (;;) /* the test resets the board (or stops qemu) */
        board_idle();
#endif
    return 0;
}
