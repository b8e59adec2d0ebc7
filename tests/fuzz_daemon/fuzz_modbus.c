/* Fuzz target "modbus": arbitrary bytes as a Modbus TCP byte stream to a
 * daemon serving unit 1 (the paper's data set, solved) and unit 2 (type-1
 * 2x2, empty), through the daemon's own code in two passes:
 *
 *  A  request path: the stream is cut into ADUs by the MBAP length as the
 *     daemon does, each ADU goes to mb_req_handle() on a libmodbus TCP
 *     context over a socketpair, held replies are released after a
 *     simulated group commit (models_pass_end + mb_req_release, as main.c).
 *     Per request: exactly one reply, well-formed (MBAP length matches,
 *     transaction id, protocol 0 and unit echoed, function or function |
 *     0x80 with a defined exception code, byte counts match the request);
 *     a request answered with an exception leaves the model as it was
 *     (struct model minus the request/exception counters, last_err and the
 *     grid cache), including writes whose WAL commit failed (rolled back).
 *  B  framing path: the same bytes, in chunks, through mb_tcp's accept and
 *     receive handlers (fake loop, AF_UNIX stream socket in place of TCP).
 *     Every complete request before the first framing error gets its reply
 *     in order; a framing error closes the connection; a half-sent request
 *     is closed by the byte timeout (fake clock).
 *
 * Byte 0 of the input: bits 0-1 float word order, bit 2 the WAL append
 * fails, bit 3 the group commit fails, bits 4-7 chunk size for pass B. */
#include <errno.h>
#include <fcntl.h>
#include <modbus.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "conf.h"
#include "fake_env.h"
#include "mb_map.h"
#include "mb_req.h"
#include "mb_tcp.h"
#include "models.h"
#include "fuzz_model_check.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define MBAP_MAX 254u /* MBAP length field: unit id + PDU of at most 253 */
#define NUNITS FUZZ_STANDARD_MODELS

static struct model *pristine[NUNITS]; /* models_dup copies */
static struct mb_map_opts opts = { 0, 100, 5, 5, { 0 }, 0, 0 };
static struct mb_req_session sess;
static int pair[2];            /* pass A: [0] daemon side, [1] harness side */
static int tcp_listener = -1;  /* the fd mb_tcp registered its accept handler on */
static int unix_listener = -1; /* what the accept handler is handed instead */
static struct sockaddr_un unix_addr;
static socklen_t unix_addr_len;
static int journal_fails, commit_fails;
static struct conf tcp_conf;

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

static void nonblock(int fd)
{
    fuzz_check(fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK) == 0, "O_NONBLOCK");
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    fuzz_standard_models(4);
    for (int k = 0; k < NUNITS; k++)
        pristine[k] = models_dup(models_at(k));
    models_set_journal(journal, NULL);

    /* Pass A: a libmodbus TCP context on a socketpair. */
    fuzz_check(socketpair(AF_UNIX, SOCK_STREAM, 0, pair) == 0, "socketpair");
    nonblock(pair[1]);
    modbus_t *ctx = modbus_new_tcp_pi(NULL, "502");
    fuzz_check(ctx != NULL && mb_req_session_init(&sess, ctx, 1) == 0, "session");
    modbus_set_socket(ctx, pair[0]);

    /* Pass B: mb_tcp with one real listener on an ephemeral loopback
     * port (its accept handler is what we need), then an AF_UNIX listener
     * whose connections that handler accepts. */
    memset(&tcp_conf, 0, sizeof tcp_conf);
    snprintf(tcp_conf.listen[0].host, sizeof tcp_conf.listen[0].host, "127.0.0.1");
    snprintf(tcp_conf.listen[0].port, sizeof tcp_conf.listen[0].port, "0");
    tcp_conf.nlisten = 1;
    tcp_conf.max_clients = 2;
    tcp_conf.max_pending = 16;
    tcp_conf.idle_timeout = 300;
    tcp_conf.byte_timeout = 500;
    fuzz_check(mb_tcp_start(&tcp_conf, &opts) == 0, "mb_tcp_start");
    fuzz_check(fake_fd_last() != NULL, "listener registered");
    tcp_listener = fake_fd_last()->fd;
    unix_listener = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    memset(&unix_addr, 0, sizeof unix_addr);
    unix_addr.sun_family = AF_UNIX;
    /* Abstract name: nothing on disk to clean up. */
    int n = snprintf(unix_addr.sun_path + 1, sizeof unix_addr.sun_path - 1, "it2n-fuzzd-%d", (int)getpid());
    unix_addr_len = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + 1 + (size_t)n);
    fuzz_check(unix_listener >= 0 && bind(unix_listener, (struct sockaddr *)&unix_addr, unix_addr_len) == 0 &&
                   listen(unix_listener, 4) == 0,
               "unix listener");
    return 0;
}

static unsigned u16at(const uint8_t *p)
{
    return (unsigned)p[0] << 8 | p[1];
}

/* Model contents a failed request must not change: everything except the
 * request/exception counters, the last error (the report of the failure)
 * and the sample grid cache. */
static int same_model(const struct model *a, const struct model *b)
{
    return a->id == b->id && a->unit == b->unit && a->state == b->state && a->gen == b->gen &&
           a->points_rx == b->points_rx && a->solves == b->solves &&
           memcmp(&a->ds, &b->ds, sizeof a->ds) == 0 && memcmp(&a->mdl, &b->mdl, sizeof a->mdl) == 0 &&
           memcmp(a->mb.upload, b->mb.upload, sizeof a->mb.upload) == 0 && fuzz_bs_same(a, b);
}

/* Check one reply ADU against its request. Returns 1 for an exception. */
static int check_reply(const uint8_t *req, size_t reqlen, const uint8_t *rep, size_t replen)
{
    unsigned fc = req[7];
    fuzz_note("request fc %u (%zu bytes), reply %zu bytes fc %u", fc, reqlen, replen, replen > 7 ? rep[7] : 0u);
    fuzz_check(replen >= 9 && replen <= MODBUS_TCP_MAX_ADU_LENGTH, "reply size");
    fuzz_check(u16at(rep + 4) == replen - 6, "reply MBAP length matches its size");
    fuzz_check(rep[0] == req[0] && rep[1] == req[1], "reply echoes the transaction id");
    fuzz_check(rep[2] == 0 && rep[3] == 0, "reply protocol id 0");
    fuzz_check(rep[6] == req[6], "reply echoes the unit id");
    if (rep[7] & 0x80u) {
        /* An exception: the request's function with bit 7 set. A request
         * function >= 0x80 (none exists) comes back unchanged with 01 (or
         * 0B for an unknown unit), never as (fc + 0x80) & 0xFF, which read
         * as a normal reply (security finding 6). */
        unsigned code = rep[8];
        fuzz_check(rep[7] == (fc | 0x80u), "exception reply: the request function with bit 7 set");
        fuzz_check(replen == 9, "exception reply is 9 bytes");
        fuzz_check(code == MB_MAP_ILLEGAL_FUNCTION || code == MB_MAP_ILLEGAL_ADDRESS || code == MB_MAP_ILLEGAL_VALUE ||
                       code == MB_MAP_DEVICE_FAILURE || code == MB_MAP_BUSY || code == MB_MAP_GATEWAY_TARGET,
                   "exception code is one the daemon defines");
        fuzz_check(!(fc & 0x80u) || code == MB_MAP_ILLEGAL_FUNCTION || code == MB_MAP_GATEWAY_TARGET,
                   "a function code >= 0x80 gets exception 01 (0B: unknown unit)");
        return 1;
    }
    fuzz_check(rep[7] == fc, "reply function code echoes the request");
    switch (fc) {
    case MODBUS_FC_READ_HOLDING_REGISTERS:
    case MODBUS_FC_READ_INPUT_REGISTERS:
        fuzz_check(reqlen == 12 && rep[8] == 2 * u16at(req + 10) && replen == 9u + rep[8], "read reply byte count");
        break;
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
        fuzz_check(reqlen == 12 && replen == 12 && memcmp(req + 7, rep + 7, 5) == 0, "write single echoes");
        break;
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS:
        fuzz_check(replen == 12 && memcmp(req + 7, rep + 7, 5) == 0, "write multiple echoes address and count");
        break;
    case MODBUS_FC_WRITE_AND_READ_REGISTERS:
        fuzz_check(rep[8] == 2 * u16at(req + 10) && replen == 9u + rep[8], "FC23 reply byte count");
        break;
    default:
        fuzz_check(0, "a normal reply to a function the daemon does not serve");
    }
    return 0;
}

static size_t drain(int fd, uint8_t *buf, size_t cap)
{
    size_t n = 0;
    for (;;) {
        ssize_t r = recv(fd, buf + n, cap - n, 0);
        if (r <= 0) {
            fuzz_check(r == 0 || errno == EAGAIN || errno == EWOULDBLOCK, "harness recv");
            return n;
        }
        n += (size_t)r;
        fuzz_check(n < cap, "harness reply buffer");
    }
}

/* Length of the complete ADU at d (0: incomplete, -1: framing error). */
static long mbap_frame(const uint8_t *d, size_t n)
{
    if (n < 7)
        return 0;
    unsigned len = u16at(d + 4);
    if (u16at(d + 2) != 0 || len < 2 || len > MBAP_MAX)
        return -1;
    return n >= 6u + len ? (long)(6u + len) : 0;
}

static void pass_a(const uint8_t *d, size_t n)
{
    static struct model *before;
    static uint8_t rep[1024];
    long len;
    memset(&sess.q, 0, sizeof sess.q);
    sess.held_len = 0;
    while ((len = mbap_frame(d, n)) > 0) {
        struct model *md = models_by_unit(d[6]);
        int ok = 1, rc;
        if (md) {
            free(before);
            before = models_dup(md);
        }
        rc = mb_req_handle(&sess, d, (int)len, &opts);
        fuzz_check(rc == 0 || rc == 1, "mb_req_handle answers (send to a socketpair cannot fail)");
        if (rc == 1) {
            /* As the daemon's post-iteration hook: commit, end the pass,
             * answer the held request. */
            ok = !commit_fails;
            end_pass(ok);
            fuzz_check(mb_req_release(&sess, ok) == 0, "mb_req_release");
        } else {
            end_pass(1);
        }
        size_t got = drain(pair[1], rep, sizeof rep);
        fuzz_check(got > 0, "every complete request gets a reply");
        int exc = check_reply(d, (size_t)len, rep, got);
        if (getenv("IT2N_FUZZ_VERBOSE"))
            fprintf(stderr, "A: unit %u fc %u -> %s %u (rc %d)\n", d[6], d[7], exc ? "exception" : "reply", rep[8], rc);
        fuzz_check(md != NULL || exc, "unknown unit answered with an exception");
        if (exc && md) {
            /* Also FC 23 whose read half failed after its write half was
             * applied: rolled back (security finding 8). */
            fuzz_check(same_model(md, before), "a request answered with an exception leaves the model unchanged");
        }
        d += len;
        n -= (size_t)len;
    }
}

/* Pass B helpers: serve the accepted connection until it has consumed
 * everything sent (or is closed). */
static void pump(int srv)
{
    for (int guard = 0; guard < 100000; guard++) {
        const struct fake_fd *f = fake_fd_find(srv);
        int avail = 0;
        if (!f)
            return;
        if (f->events == 0) { /* reply held for the commit */
            int ok = !commit_fails;
            end_pass(ok);
            mb_tcp_release(ok);
            continue;
        }
        fuzz_check(ioctl(srv, FIONREAD, &avail) == 0, "FIONREAD");
        if (avail == 0)
            return;
        fake_fd_dispatch(srv, POLLIN);
        end_pass(1);
    }
    fuzz_check(0, "connection makes progress");
}

static void pass_b(const uint8_t *d, size_t n, size_t chunk)
{
    static uint8_t rep[1 << 18];
    size_t got = 0, sent = 0;
    int cli = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    fuzz_check(cli >= 0 && connect(cli, (struct sockaddr *)&unix_addr, unix_addr_len) == 0, "connect");
    nonblock(cli);
    fuzz_check(fake_fd_dispatch_as(tcp_listener, unix_listener, POLLIN) == 0, "accept handler");
    fuzz_check(mb_tcp_clients() == 1 && fake_fd_last() != NULL, "connection accepted");
    int srv = fake_fd_last()->fd;
    while (sent < n && fake_fd_find(srv)) {
        size_t k = n - sent < chunk ? n - sent : chunk;
        ssize_t w = send(cli, d + sent, k, MSG_NOSIGNAL);
        if (w < 0 && errno == EPIPE)
            break;
        fuzz_check(w > 0, "harness send");
        sent += (size_t)w;
        pump(srv);
        got += drain(cli, rep + got, sizeof rep - got);
    }
    /* Replies: one per complete request before the first framing error,
     * in order. */
    size_t pos = 0, rpos = 0;
    long len;
    int framing_error = 0;
    while ((len = mbap_frame(d + pos, n - pos)) != 0) {
        if (len < 0) {
            framing_error = 1;
            break;
        }
        fuzz_check(got - rpos >= 9, "pass B: a reply for every complete request");
        size_t rl = 6u + u16at(rep + rpos + 4);
        fuzz_check(rl <= got - rpos, "pass B: reply complete");
        check_reply(d + pos, (size_t)len, rep + rpos, rl);
        pos += (size_t)len;
        rpos += rl;
    }
    fuzz_check(rpos == got, "pass B: no reply without a request");
    if (framing_error) {
        fuzz_check(fake_fd_find(srv) == NULL, "framing error closes the connection");
    } else if (pos < n) {
        /* Half-sent request: the byte timeout closes it. */
        fuzz_check(fake_fd_find(srv) != NULL, "incomplete request keeps the connection");
        fake_advance((uint64_t)tcp_conf.byte_timeout + 200);
        fuzz_check(fake_fd_find(srv) == NULL, "byte timeout closes a half-sent request");
    } else if (fake_fd_find(srv)) {
        close(cli);
        cli = -1;
        fake_fd_dispatch(srv, POLLIN); /* end of file */
    }
    fuzz_check(mb_tcp_clients() == 0, "connection closed");
    if (cli >= 0)
        close(cli);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1 || size > 8192)
        return 0;
    opts.word_order = data[0] & 3;
    journal_fails = (data[0] >> 2) & 1;
    commit_fails = (data[0] >> 3) & 1;
    size_t chunk = (size_t)(data[0] >> 4) * 17u + 1u;

    for (int k = 0; k < NUNITS; k++)
        models_copy(models_at(k), pristine[k]);
    pass_a(data + 1, size - 1);
    for (int k = 0; k < NUNITS; k++)
        models_copy(models_at(k), pristine[k]);
    pass_b(data + 1, size - 1, chunk);
    (void)fake_log_errors();
    return 0;
}
