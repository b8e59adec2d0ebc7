/* Fuzz target "rtu": arbitrary bytes on a Modbus RTU line into mb_rtu's
 * framer (length from the function code, CRC-16, inter-frame silence
 * t3.5) and on to mb_req, with unit 1 (the paper's data set, solved) and
 * unit 2 (type-1 2x2, empty) on the bus.
 *
 * The port is opened the daemon's way (modbus_new_rtu + modbus_connect on
 * a pty), then a socketpair end is dup2()ed over its fd so the harness can
 * feed and read bytes synchronously; silence is simulated with the fake
 * clock (the sweep timer runs when the harness advances it).
 *
 * Input: byte 0 bit 0 the WAL append fails, bit 1 the group commit fails;
 * then steps [ctrl][data...]: ctrl bits 0-5 give 1..64 data bytes, bit 6 a
 * silence (> t3.5) after them, bit 7 a short gap (< t3.5).
 * Invariants: no crash/UB/leak; every reply is a well-formed RTU frame
 * (CRC, a served unit, function echoed or an exception with a defined
 * code, length consistent with the function); nothing is ever sent for
 * another unit or broadcast; after a silence the framer is back in sync (a
 * valid request gets its exact reply); the port stays open (found here and
 * fixed: more than 256 bytes without a silence filled the frame buffer and
 * the next read(fd, buf, 0) returned 0, taken for end of file, closing the
 * port for 500 ms; corpus/rtu/noise_long); a function framed by silence is
 * answered exactly t3.5 (to the µs of the fake clock) after its last byte. */
#include <errno.h>
#include <fcntl.h>
#include <pty.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include "conf.h"
#include "fake_env.h"
#include "mb_map.h"
#include "mb_req.h"
#include "mb_rtu.h"
#include "models.h"
#include "fuzz_model_check.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define NUNITS FUZZ_STANDARD_MODELS
static struct model *pristine[NUNITS]; /* models_dup copies */
static struct mb_map_opts opts = { 0, 100, 5, 5, { 0 }, 0, 0 };
static struct conf rtu_conf;
static int pty_master = -1;
static int journal_fails, commit_fails;

static int journal(void *arg, const struct model_rec *rec)
{
    (void)arg;
    (void)rec;
    return journal_fails ? -1 : 0;
}

static void end_pass(int ok)
{
    models_pass_end(ok, NULL, NULL);
}

static uint16_t crc16(const uint8_t *p, size_t n)
{
    uint16_t crc = 0xFFFF;
    while (n--) {
        crc ^= *p++;
        for (int k = 0; k < 8; k++)
            crc = (uint16_t)((crc & 1) ? (crc >> 1) ^ 0xA001 : crc >> 1);
    }
    return crc;
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    char name[64];
    int slave;
    (void)argc;
    (void)argv;
    fuzz_standard_models(4);
    for (int k = 0; k < NUNITS; k++)
        pristine[k] = models_dup(models_at(k));
    models_set_journal(journal, NULL);
    /* A pty gives modbus_connect() a terminal to configure. */
    fuzz_check(openpty(&pty_master, &slave, name, NULL, NULL) == 0, "openpty");
    close(slave);
    memset(&rtu_conf, 0, sizeof rtu_conf);
    rtu_conf.nrtu = 1;
    snprintf(rtu_conf.rtu[0].name, sizeof rtu_conf.rtu[0].name, "fuzz");
    snprintf(rtu_conf.rtu[0].device, sizeof rtu_conf.rtu[0].device, "%s", name);
    rtu_conf.rtu[0].baud = 19200;
    rtu_conf.rtu[0].parity = 'N';
    rtu_conf.rtu[0].stop_bits = 1;
    return 0;
}

/* Serve the port until it has read everything sent; returns 0 if the port
 * closed itself. */
static int pump(int port)
{
    for (int guard = 0; guard < 100000; guard++) {
        int avail = 0;
        if (!fake_fd_find(port))
            return 0;
        /* Held replies are released after the group commit, as main.c. */
        int ok = !commit_fails;
        end_pass(ok);
        mb_rtu_release(ok);
        fuzz_check(ioctl(port, FIONREAD, &avail) == 0, "FIONREAD");
        if (avail == 0)
            return 1;
        fake_fd_dispatch(port, POLLIN);
    }
    fuzz_check(0, "port makes progress");
    return 0;
}

static size_t drain(int fd, uint8_t *buf, size_t cap)
{
    size_t n = 0;
    for (;;) {
        ssize_t r = read(fd, buf + n, cap - n);
        if (r <= 0) {
            /* ECONNRESET: the port closed itself with bytes unread. */
            fuzz_check(r == 0 || errno == EAGAIN || errno == EWOULDBLOCK || errno == ECONNRESET, "harness read");
            return n;
        }
        n += (size_t)r;
        fuzz_check(n < cap, "harness reply buffer");
    }
}

static int crc_ok(const uint8_t *f, size_t len)
{
    return len >= 4 && (uint16_t)(f[len - 2] | f[len - 1] << 8) == crc16(f, len - 2);
}

/* Check a stream of replies; returns how many. */
static unsigned check_replies(const uint8_t *r, size_t n)
{
    unsigned count = 0;
    size_t pos = 0;
    while (pos < n) {
        const uint8_t *f = r + pos;
        size_t left = n - pos, len;
        fuzz_check(left >= 5, "reply frame at least 5 bytes");
        fuzz_check(models_by_unit(f[0]) != NULL, "replies only for served units (never broadcast)");
        fuzz_note("reply unit %u fc %u byte 2 %u (%zu bytes left)", f[0], f[1], f[2], left);
        if (f[1] & 0x80u) {
            /* Exception: function with bit 7 set (a request function >=
             * 0x80 comes back unchanged with 01, security finding 6). */
            fuzz_check(crc_ok(f, 5), "exception reply CRC");
            unsigned fc = f[1] & 0x7Fu;
            fuzz_check(fc == 3 || fc == 4 || fc == 6 || fc == 16 || fc == 23 || f[2] == MB_MAP_ILLEGAL_FUNCTION,
                       "an unserved function gets exception 01");
            fuzz_check(f[2] == MB_MAP_ILLEGAL_FUNCTION || f[2] == MB_MAP_ILLEGAL_ADDRESS || f[2] == MB_MAP_ILLEGAL_VALUE ||
                           f[2] == MB_MAP_DEVICE_FAILURE || f[2] == MB_MAP_BUSY,
                       "exception code is one the daemon defines");
            len = 5;
        } else {
            switch (f[1]) {
            case 3: case 4: case 23: len = 5u + f[2]; fuzz_check(f[2] % 2 == 0, "even byte count"); break;
            case 6: case 16: len = 8; break;
            default: len = 0; fuzz_check(0, "reply function is one the daemon serves"); break;
            }
            fuzz_check(len <= left && crc_ok(f, len), "reply CRC and length");
        }
        pos += len;
        count++;
    }
    return count;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static uint8_t rep[1 << 17];
    int sp[2];
    size_t got = 0;
    if (size < 1 || size > 8192)
        return 0;
    journal_fails = data[0] & 1;
    commit_fails = (data[0] >> 1) & 1;
    for (int k = 0; k < NUNITS; k++)
        models_copy(models_at(k), pristine[k]);

    /* Open the port the daemon's way, then swap the tty for a socket. */
    fake_reset();
    fuzz_check(mb_rtu_start(&rtu_conf, &opts) == 0 && fake_fd_last() != NULL, "mb_rtu_start");
    int port = fake_fd_last()->fd;
    fuzz_check(socketpair(AF_UNIX, SOCK_STREAM, 0, sp) == 0, "socketpair");
    fuzz_check(fcntl(sp[0], F_SETFL, O_NONBLOCK) == 0 && fcntl(sp[1], F_SETFL, O_NONBLOCK) == 0, "O_NONBLOCK");
    fuzz_check(dup2(sp[0], port) == port, "dup2");
    close(sp[0]);
    int line = sp[1];

    size_t pos = 1;
    int open = 1;
    while (pos < size && open) {
        uint8_t c = data[pos++];
        size_t n = (size_t)(c & 0x3Fu) + 1u;
        if (n > size - pos)
            n = size - pos;
        fuzz_check(write(line, data + pos, n) == (ssize_t)n, "harness write");
        pos += n;
        open = pump(port);
        if (c & 0x40u)
            fake_advance(25); /* silence: the sweep settles the frame */
        else if (c & 0x80u)
            fake_advance(1);
        open = open && pump(port);
        got += drain(line, rep + got, sizeof rep - got);
    }
    fuzz_check(open, "the port stays open whatever arrives");
    if (open) {
        /* Silence, then a valid request: the framer is back in sync. */
        static const uint8_t probe[6] = { 1, 3, 0, IT2N_REGMAP_REG_N, 0, 2 };
        uint8_t req[8], ans[64];
        fake_advance(25);
        pump(port);
        got += drain(line, rep + got, sizeof rep - got);
        memcpy(req, probe, 6);
        uint16_t crc = crc16(req, 6);
        req[6] = (uint8_t)crc;
        req[7] = (uint8_t)(crc >> 8);
        fuzz_check(write(line, req, 8) == 8, "probe write");
        fuzz_check(pump(port), "port open after the probe");
        size_t an = drain(line, ans, sizeof ans);
        fuzz_note("probe answer %zu bytes", an);
        fuzz_check(an == 9 && ans[0] == 1 && ans[1] == 3 && ans[2] == 4 && crc_ok(ans, 9), "in sync after a silence");
        struct model *md = models_by_unit(1);
        fuzz_check(ans[3] == 0 && ans[4] == md->ds.n && ans[5] == 0 && ans[6] == md->ds.m, "probe reads n, m");

        /* The silence is t3.5 of the Modbus serial line spec, to the µs
         * (19200 Bd 8N1: 3.5 x 10 bits = 1823 us): a function framed only
         * by silence (17) is answered after exactly that, not before. */
        uint8_t fn17[4] = { 1, 17, 0, 0 };
        crc = crc16(fn17, 2);
        fn17[2] = (uint8_t)crc;
        fn17[3] = (uint8_t)(crc >> 8);
        fuzz_check(write(line, fn17, 4) == 4, "fn17 write");
        fuzz_check(pump(port), "port open after fn17");
        fake_advance_us(1822);
        pump(port);
        fuzz_check(drain(line, ans, sizeof ans) == 0, "nothing answered before t3.5 (1823 us)");
        fake_advance_us(1);
        pump(port);
        an = drain(line, ans, sizeof ans);
        fuzz_check(an == 5 && ans[0] == 1 && ans[1] == 0x91 && ans[2] == MB_MAP_ILLEGAL_FUNCTION && crc_ok(ans, 5),
                   "exception 01 at t3.5 after a function framed by silence");
    }
    unsigned replies = check_replies(rep, got);
    if (getenv("IT2N_FUZZ_VERBOSE"))
        fprintf(stderr, "rtu: %u repl%s, port %s\n", replies, replies == 1 ? "y" : "ies", open ? "open" : "closed");
    mb_rtu_stop();
    close(line);
    (void)fake_log_errors();
    return 0;
}
