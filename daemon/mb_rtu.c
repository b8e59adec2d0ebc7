/* mb_rtu.c — see mb_rtu.h.
 *
 * libmodbus' modbus_receive() blocks until a frame is complete, which would
 * stall the loop; instead bytes are read non-blocking and a request frame
 * is complete when its length (known from the function code: 8 bytes for
 * 03/04/06, 9 + n for 16, 13 + n for 23) has arrived with a valid CRC; it
 * is answered at once. A frame that never completes, or has an unknown
 * function code, is settled by the inter-frame silence t3.5 of the Modbus
 * serial line specification (3.5 character times, 1750 us above 19200 Bd),
 * timed to the microsecond by a one-shot loop timer re-armed at every
 * read. Bytes already waiting when the loop wakes are read before timers
 * run, so a loop held up by other work never splits a frame.
 *
 * On a shared bus other slaves' replies arrive too. Bytes that cannot start
 * a request (a length-complete candidate whose CRC fails: a CRC error or
 * another device's frame) are dropped one at a time, and a complete request
 * with a valid CRC further on in the buffer (a silence the reads did not
 * see) ends whatever came before it. CRC errors are never answered, as the
 * RTU specification requires. */
#include "mb_rtu.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/serial.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include "link_serial.h"
#include "log.h"
#include "loop.h"
#include "mb_req.h"

struct rtu_port {
    struct conf_rtu cfg;
    modbus_t *ctx;
    int fd;
    struct mb_req_session s;
    uint8_t buf[MODBUS_RTU_MAX_ADU_LENGTH];
    size_t len;
    size_t checked;   /* candidates ending at or before this were checked */
    uint64_t last_rx; /* us */
    unsigned gap_us;  /* t3.5 */
    long silence_timer;
    long retry_timer;
    unsigned backoff_ms;
};

_Static_assert(CONF_RTS_NONE == MODBUS_RTU_RTS_NONE && CONF_RTS_UP == MODBUS_RTU_RTS_UP &&
                   CONF_RTS_DOWN == MODBUS_RTU_RTS_DOWN,
               "conf_rts values are libmodbus' MODBUS_RTU_RTS_*");

static struct rtu_port ports[CONF_MAX_RTU];
static int nports;
static struct mb_map_opts opts;
static uint16_t crc_table[256];

static uint16_t crc16(const uint8_t *p, size_t n)
{
    uint16_t crc = 0xFFFF;
    if (!crc_table[1])
        for (unsigned b = 0; b < 256; b++) {
            uint16_t c = (uint16_t)b;
            for (int k = 0; k < 8; k++)
                c = (uint16_t)((c & 1) ? (c >> 1) ^ 0xA001 : c >> 1);
            crc_table[b] = c;
        }
    while (n--)
        crc = (uint16_t)(crc >> 8 ^ crc_table[(crc ^ *p++) & 0xFF]);
    return crc;
}

static int crc_ok(const uint8_t *b, size_t n)
{
    return n >= 4 && (b[n - 2] | b[n - 1] << 8) == crc16(b, n - 2);
}

/* t3.5: 3.5 character times (start + 8 data + parity + stop bits) up to
 * 19200 Bd, 1750 us above (Modbus over serial line V1.02, 2.5.1.1). */
static unsigned t35_us(const struct conf_rtu *c)
{
    unsigned bits = 1u + 8u + (c->parity != 'N') + (unsigned)c->stop_bits;
    if (c->t35_us > 0)
        return (unsigned)c->t35_us;
    if (c->baud > 19200)
        return 1750;
    return (unsigned)((3500000ull * bits + (unsigned)c->baud - 1) / (unsigned)c->baud);
}

/* Expected request length from what we have, 0 if not yet known, -1 if
 * the function code gives no length (settle by silence). */
static long expected_len(const uint8_t *b, size_t n)
{
    if (n < 2)
        return 0;
    switch (b[1]) {
    case 3:
    case 4:
    case 6: return 8;
    case 16: return n < 7 ? 0 : 9 + (long)b[6];
    case 23: return n < 11 ? 0 : 13 + (long)b[10];
    default: return -1;
    }
}

static void drop(struct rtu_port *p, size_t n)
{
    memmove(p->buf, p->buf + n, p->len - n);
    p->len -= n;
    p->checked = p->checked > n ? p->checked - n : 0;
}

static void port_open(void *arg);
static void arm_silence(struct rtu_port *p);

static void port_fail(struct rtu_port *p, const char *why)
{
    log_warn("rtu %s (%s): %s; reopening in %u ms", p->cfg.name, p->cfg.device, why, p->backoff_ms);
    if (p->fd >= 0)
        loop_del_fd(p->fd);
    if (p->ctx) {
        modbus_close(p->ctx);
        modbus_free(p->ctx);
        mb_req_session_free(&p->s);
    }
    p->ctx = NULL;
    p->fd = -1;
    p->len = 0;
    p->checked = 0;
    if (p->silence_timer)
        loop_cancel_timer(p->silence_timer);
    p->silence_timer = 0;
    p->retry_timer = loop_add_timer(p->backoff_ms, port_open, p);
    p->backoff_ms = p->backoff_ms * 2 > 30000 ? 30000 : p->backoff_ms * 2;
}

static int handle_frame(struct rtu_port *p, size_t n)
{
    if (!crc_ok(p->buf, n)) {
        log_debug("rtu %s: CRC error, %zu byte(s) dropped", p->cfg.name, n);
        drop(p, n);
        return 0;
    }
    int rc = mb_req_handle(&p->s, p->buf, (int)n, &opts);
    drop(p, n);
    if (rc < 0)
        port_fail(p, "write failed");
    return rc;
}

/* Offset (> 0) of a complete request with a valid CRC in the buffer, or 0.
 * Each candidate is checked once, when its last byte has arrived. */
static size_t scan(const struct rtu_port *p)
{
    for (size_t i = 1; i + 8 <= p->len; i++) {
        long w = expected_len(p->buf + i, p->len - i);
        if (w <= 0 || i + (size_t)w > p->len || i + (size_t)w <= p->checked)
            continue;
        if (crc_ok(p->buf + i, (size_t)w))
            return i;
    }
    return 0;
}

/* The bytes before offset n are a frame of their own (a silence ended it):
 * one with a function the daemon does not frame by length is handled
 * (exception 01 if it is for us), anything else is dropped. */
static int settle(struct rtu_port *p, size_t n)
{
    if (n >= 4 && expected_len(p->buf, n) < 0 && crc_ok(p->buf, n))
        return handle_frame(p, n);
    log_debug("rtu %s: %zu byte(s) without a request dropped", p->cfg.name, n);
    drop(p, n);
    return 0;
}

static void process(struct rtu_port *p)
{
    while (p->len && !p->s.held_len && p->ctx) {
        long want = expected_len(p->buf, p->len);
        if (want > 0 && (size_t)want <= p->len) {
            if (crc_ok(p->buf, (size_t)want)) {
                if (handle_frame(p, (size_t)want) < 0)
                    return;
                continue;
            }
            /* Not the start of a request (CRC error, another device's
             * frame): look from the next byte on. */
            drop(p, 1);
            continue;
        }
        if (want > (long)sizeof p->buf) {
            drop(p, 1);
            continue;
        }
        size_t at = scan(p);
        if (at) {
            if (settle(p, at) < 0)
                return;
            continue;
        }
        if (p->len == sizeof p->buf) { /* full, and no request in it */
            drop(p, 1);
            continue;
        }
        break;
    }
    p->checked = p->len;
}

static void on_port(void *arg, int fd, short revents)
{
    struct rtu_port *p = arg;
    ssize_t r;
    if (revents & (POLLERR | POLLHUP | POLLNVAL)) {
        port_fail(p, "hang-up or error");
        return;
    }
    if (p->len == sizeof p->buf) {
        /* A full buffer without a silence holds no request (noise, another
         * slave babbling): drop it and resync, rather than read 0 bytes and
         * take that for end of file. */
        log_debug("rtu %s: %zu bytes without a frame; dropped", p->cfg.name, p->len);
        drop(p, p->len);
    }
    r = read(fd, p->buf + p->len, sizeof p->buf - p->len);
    if (r <= 0) {
        if (r < 0 && (errno == EAGAIN || errno == EINTR))
            return;
        port_fail(p, r ? strerror(errno) : "end of file");
        return;
    }
    p->len += (size_t)r;
    p->last_rx = loop_now_us();
    p->backoff_ms = 500;
    process(p);
    arm_silence(p);
}

/* t3.5 after the last byte: the frame in the buffer is over. An incomplete
 * one is dropped; one with a function the daemon does not frame by length
 * is complete and answered (exception 01 if it is ours). */
static void on_silence(void *arg)
{
    struct rtu_port *p = arg;
    p->silence_timer = 0;
    if (!p->ctx || !p->len)
        return;
    if (p->s.held_len) { /* answered after the commit; look again then */
        arm_silence(p);
        return;
    }
    settle(p, p->len);
    process(p);
    arm_silence(p);
}

static void arm_silence(struct rtu_port *p)
{
    if (p->silence_timer)
        loop_cancel_timer(p->silence_timer);
    p->silence_timer = 0;
    if (p->ctx && p->len) {
        uint64_t now = loop_now_us(), due = p->last_rx + p->gap_us;
        p->silence_timer = loop_add_timer_us(due > now ? due - now : 0, on_silence, p);
    }
}

/* Kernel RS-485: the driver switches the transceiver. Enabled through
 * libmodbus, then the options set on the same descriptor and read back:
 * drivers clamp delays and drop flags they cannot do without an error.
 * On a refusal returns -1 with what was refused in why; *on says whether
 * the port is in RS-485 mode all the same (with the driver's settings). */
static int rs485_kernel(const struct rtu_port *p, int *on, char *why, size_t size)
{
    const struct conf_rtu *c = &p->cfg;
    struct serial_rs485 want, got;
    int fd = modbus_get_socket(p->ctx);
    size_t n = 0;
    *on = 0;
    if (modbus_rtu_set_serial_mode(p->ctx, MODBUS_RTU_RS485)) {
        snprintf(why, size, "RS-485 mode (rs485 = yes, TIOCSRS485): %s", strerror(errno));
        return -1;
    }
    *on = 1;
    if (c->rts_on_send < 0 && c->delay_before_ms < 0 && c->delay_after_ms < 0 && c->termination < 0)
        return 0;
    memset(&want, 0, sizeof want);
    if (ioctl(fd, TIOCGRS485, &want)) {
        snprintf(why, size, "reading the RS-485 settings (TIOCGRS485): %s", strerror(errno));
        return -1;
    }
    if (c->rts_on_send >= 0) {
        want.flags &= ~(__u32)(SER_RS485_RTS_ON_SEND | SER_RS485_RTS_AFTER_SEND);
        want.flags |= c->rts_on_send ? SER_RS485_RTS_ON_SEND : SER_RS485_RTS_AFTER_SEND;
    }
    if (c->termination >= 0)
        want.flags =
            c->termination ? want.flags | SER_RS485_TERMINATE_BUS : want.flags & ~(__u32)SER_RS485_TERMINATE_BUS;
    if (c->delay_before_ms >= 0)
        want.delay_rts_before_send = (__u32)c->delay_before_ms;
    if (c->delay_after_ms >= 0)
        want.delay_rts_after_send = (__u32)c->delay_after_ms;
    got = want;
    if (ioctl(fd, TIOCSRS485, &got) || ioctl(fd, TIOCGRS485, &got)) {
        snprintf(why, size, "the RS-485 options (TIOCSRS485): %s", strerror(errno));
        return -1;
    }
    why[0] = 0;
#define DIFF(cond, ...)                                            \
    do {                                                           \
        if ((cond) && n < size)                                    \
            n += (size_t)snprintf(why + n, size - n, __VA_ARGS__); \
    } while (0)
    DIFF(c->rts_on_send >= 0 && !(got.flags & SER_RS485_RTS_ON_SEND) != !c->rts_on_send,
         "%srs485_rts_on_send = %s (the driver keeps it %s)", n ? ", " : "", c->rts_on_send ? "high" : "low",
         got.flags & SER_RS485_RTS_ON_SEND ? "high" : "low");
    DIFF(c->termination >= 0 && !(got.flags & SER_RS485_TERMINATE_BUS) != !c->termination,
         "%srs485_termination = %s (not supported by the driver)", n ? ", " : "", c->termination ? "yes" : "no");
    DIFF(c->delay_before_ms >= 0 && got.delay_rts_before_send != want.delay_rts_before_send,
         "%srs485_delay_before_send_ms = %d (the driver uses %u)", n ? ", " : "", c->delay_before_ms,
         (unsigned)got.delay_rts_before_send);
    DIFF(c->delay_after_ms >= 0 && got.delay_rts_after_send != want.delay_rts_after_send,
         "%srs485_delay_after_send_ms = %d (the driver uses %u)", n ? ", " : "", c->delay_after_ms,
         (unsigned)got.delay_rts_after_send);
#undef DIFF
    return n ? -1 : 0;
}

/* RTS switched by libmodbus around each reply. libmodbus ignores the
 * modem-control ioctl's result, so whether the device has an RTS line
 * (a pty has none) is asked here first. */
static int rs485_libmodbus_rts(const struct rtu_port *p, char *why, size_t size)
{
    const struct conf_rtu *c = &p->cfg;
    const char *mode = c->rts == CONF_RTS_UP ? "up" : "down";
    int bits;
    if (ioctl(modbus_get_socket(p->ctx), TIOCMGET, &bits)) {
        snprintf(why, size, "RTS control (rs485_rts = %s, TIOCMGET): %s", mode, strerror(errno));
        return -1;
    }
    if (modbus_rtu_set_rts(p->ctx, c->rts) ||
        (c->rts_delay_us >= 0 && modbus_rtu_set_rts_delay(p->ctx, c->rts_delay_us))) {
        snprintf(why, size, "RTS control (rs485_rts = %s, rs485_rts_delay_us): %s", mode, modbus_strerror(errno));
        modbus_rtu_set_rts(p->ctx, MODBUS_RTU_RTS_NONE);
        return -1;
    }
    return 0;
}

/* RS-485 set-up of a freshly connected port. Returns -1 if the port must
 * not be served (rs485_strict and something refused); mode gets what the
 * port does, for the log. */
static int rs485_setup(struct rtu_port *p, char *mode, size_t size)
{
    const struct conf_rtu *c = &p->cfg;
    char why[320];
    int rc, on = 0;
    if (!c->rs485) {
        snprintf(mode, size, "RS-232");
        return 0;
    }
    if (c->rts == CONF_RTS_NONE)
        rc = rs485_kernel(p, &on, why, sizeof why);
    else
        rc = rs485_libmodbus_rts(p, why, sizeof why);
    if (!rc) {
        if (c->rts == CONF_RTS_NONE)
            snprintf(mode, size, "RS-485 (kernel)");
        else
            snprintf(mode, size, "RS-485 (RTS %s by libmodbus, %d us delay)", c->rts == CONF_RTS_UP ? "up" : "down",
                     modbus_rtu_get_rts_delay(p->ctx));
        return 0;
    }
    if (c->strict) {
        log_err("rtu %s: %s refuses %s; not served (rs485_strict = yes)", c->name, c->device, why);
        return -1;
    }
    log_warn("rtu %s: %s refuses %s; serving in %s (rs485_strict = yes would refuse the port)", c->name, c->device, why,
             on ? "RS-485 mode with the driver's settings" : "RS-232 mode");
    snprintf(mode, size, on ? "RS-485 (kernel, driver's settings)" : "RS-232 (RS-485 refused)");
    return 0;
}

static void port_open(void *arg)
{
    struct rtu_port *p = arg;
    p->retry_timer = 0;
    {
        /* Held by another process? Ask before modbus_connect, which sets
         * the line (speed, parity) and would disturb its owner. */
        int lk = open(p->cfg.device, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
        int busy = lk >= 0 && link_serial_lock(lk) != 0 && errno == EBUSY;
        if (lk >= 0)
            close(lk);
        if (busy) {
            port_fail(p, LINK_SERIAL_LOCKED);
            return;
        }
    }
    p->ctx = modbus_new_rtu(p->cfg.device, p->cfg.baud, p->cfg.parity, 8, p->cfg.stop_bits);
    if (!p->ctx) {
        port_fail(p, "bad parameters");
        return;
    }
    if (modbus_connect(p->ctx)) {
        modbus_free(p->ctx);
        p->ctx = NULL;
        port_fail(p, modbus_strerror(errno));
        return;
    }
    /* One server per bus device: a second it2nd on the same
     * port would answer every request twice (links do the same). */
    if (link_serial_lock(modbus_get_socket(p->ctx))) {
        modbus_close(p->ctx);
        modbus_free(p->ctx);
        p->ctx = NULL;
        port_fail(p, LINK_SERIAL_LOCKED);
        return;
    }
    char mode[96];
    if (rs485_setup(p, mode, sizeof mode)) {
        modbus_close(p->ctx);
        modbus_free(p->ctx);
        p->ctx = NULL;
        port_fail(p, "RS-485 set-up refused");
        return;
    }
    if (mb_req_session_init(&p->s, p->ctx, 0)) {
        modbus_close(p->ctx);
        modbus_free(p->ctx);
        p->ctx = NULL;
        port_fail(p, "out of memory");
        return;
    }
    p->s.read_only = p->cfg.read_only;
    snprintf(p->s.who, sizeof p->s.who, "rtu %s (%.100s)", p->cfg.name, p->cfg.device);
    p->fd = modbus_get_socket(p->ctx);
    fcntl(p->fd, F_SETFL, fcntl(p->fd, F_GETFL) | O_NONBLOCK);
    p->gap_us = t35_us(&p->cfg);
    p->len = 0;
    p->checked = 0;
    loop_add_fd(p->fd, POLLIN, on_port, p);
    log_notice("modbus rtu %s on %s, %d %c%d, %s, t3.5 %u us%s", p->cfg.name, p->cfg.device, p->cfg.baud, p->cfg.parity,
               p->cfg.stop_bits, mode, p->gap_us, p->cfg.read_only ? ", read-only" : "");
}

static void close_port(struct rtu_port *p)
{
    if (p->retry_timer)
        loop_cancel_timer(p->retry_timer);
    if (p->silence_timer)
        loop_cancel_timer(p->silence_timer);
    if (p->ctx) {
        loop_del_fd(p->fd);
        modbus_close(p->ctx);
        modbus_free(p->ctx);
        mb_req_session_free(&p->s);
    }
    memset(p, 0, sizeof *p);
    p->fd = -1;
}

static void open_all(const struct conf *c)
{
    for (int k = 0; k < c->nrtu; k++) {
        struct rtu_port *p = &ports[nports++];
        memset(p, 0, sizeof *p);
        p->cfg = c->rtu[k];
        p->fd = -1;
        p->backoff_ms = 500;
        port_open(p);
    }
}

int mb_rtu_start(const struct conf *c, const struct mb_map_opts *o)
{
    opts = *o;
    nports = 0;
    open_all(c);
    return 0;
}

int mb_rtu_reload(const struct conf *c, const struct mb_map_opts *o)
{
    int same = c->nrtu == nports;
    opts = *o;
    for (int k = 0; same && k < nports; k++)
        same = conf_rtu_same(&c->rtu[k], &ports[k].cfg);
    if (same)
        return 0;
    log_notice("rtu: ports changed; reopening");
    for (int k = 0; k < nports; k++)
        close_port(&ports[k]);
    nports = 0;
    open_all(c);
    return 0;
}

void mb_rtu_release(int commit_ok)
{
    mb_rtu_release_upto(UINT64_MAX, commit_ok);
}

void mb_rtu_release_upto(uint64_t batch, int commit_ok)
{
    for (int k = 0; k < nports; k++) {
        struct rtu_port *p = &ports[k];
        if (!p->ctx || !p->s.held_len || p->s.held_batch > batch)
            continue;
        if (mb_req_release(&p->s, commit_ok) < 0) {
            port_fail(p, "write failed");
            continue;
        }
        process(p);
        arm_silence(p);
        if (p->s.held_len)
            loop_wake();
    }
}

void mb_rtu_stop(void)
{
    for (int k = 0; k < nports; k++)
        close_port(&ports[k]);
    nports = 0;
}
