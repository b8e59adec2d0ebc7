/*
 * faultrelay — a serial line between two ptys that paces bytes at a baud
 * rate and injects frame faults, for the protocol benchmarks
 * (tests/bench/proto/bench_proto.py).
 *
 *   faultrelay --a PATH --b PATH [--baud B] [--drop PCT] [--dup PCT]
 *              [--reorder PCT] [--corrupt PCT] [--seed S] [--stats FILE]
 *
 * Two pty pairs; PATH names a symlink to each slave (side A for it2nd's
 * [link:], side B for the host program). Bytes written to one slave come
 * out of the other, as over a null-modem cable:
 *
 *  - pacing: each direction is a line that carries one byte per 10 bit
 *    times (8N1) at --baud (0 = unpaced). A byte comes out when the line
 *    has finished sending it; while more than 4 KiB wait for the line, the
 *    relay stops reading that side, so the writer's tty fills up and it
 *    sees back-pressure as from a real UART.
 *  - faults, per frame (bytes up to and including a 0x00 delimiter, the
 *    protocol's COBS framing, docs/protocol.md §2), each decided
 *    independently with the given percentage (fractions allowed, "0.5"):
 *    drop (never sent), corrupt (one bit of one byte other than the
 *    delimiter flipped), duplicate (sent twice in a row), reorder (held
 *    back and sent right after the next frame, or after 20 ms of silence).
 *    Each direction has its own xorshift generator, seeded from --seed
 *    (A->B) and --seed + 1 (B->A), so a run's fault pattern per frame index
 *    is fixed.
 *
 * Runs until SIGTERM/SIGINT; then writes counts per direction as JSON to
 * --stats (if given) and exits 0. The symlinks are removed at exit.
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#define QCAP (1u << 20)   /* line queue per direction, bytes */
#define READ_STOP 4096u   /* stop reading a side above this backlog */
#define FRAME_MAX 4096u   /* longer runs without a delimiter are passed as they are */
#define HOLD_NS 20000000LL /* a reordered frame waits at most this long */

typedef struct dir {
    const char *name;
    int from, to;           /* masters */
    uint64_t rng;
    uint8_t *q;             /* bytes waiting for the line */
    size_t qh, qt;          /* head (next out), tail */
    int64_t line_free;      /* ns when the line finished its last byte */
    uint8_t fr[FRAME_MAX];  /* frame being collected */
    size_t flen;
    uint8_t held[FRAME_MAX]; /* reordered frame */
    size_t hlen;
    int64_t held_at;
    unsigned long long frames, dropped, duped, reordered, corrupted, bytes_in, bytes_out;
} dir;

static volatile sig_atomic_t stop;
static double p_drop, p_dup, p_reorder, p_corrupt;
static int64_t byte_ns; /* 0: unpaced */
static char link_a[512], link_b[512], slave_a[128], slave_b[128];

static void on_sig(int s)
{
    (void)s;
    stop = 1;
}

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static uint64_t rnd(dir *d)
{
    d->rng ^= d->rng << 13;
    d->rng ^= d->rng >> 7;
    d->rng ^= d->rng << 17;
    return d->rng;
}

/* True with probability pct percent. */
static int chance(dir *d, double pct)
{
    return pct > 0 && (double)(rnd(d) % 1000000u) < pct * 10000.0;
}

static size_t qlen(const dir *d)
{
    return d->qt - d->qh;
}

static void put(dir *d, const uint8_t *p, size_t n)
{
    if (d->qh == d->qt)
        d->qh = d->qt = 0;
    if (d->qt + n > QCAP) { /* compact */
        memmove(d->q, d->q + d->qh, qlen(d));
        d->qt -= d->qh;
        d->qh = 0;
    }
    if (d->qt + n > QCAP)
        n = QCAP - d->qt; /* cannot happen with READ_STOP; never overflow */
    if (qlen(d) == 0 && d->line_free < now_ns())
        d->line_free = now_ns(); /* idle line starts now */
    memcpy(d->q + d->qt, p, n);
    d->qt += n;
}

static void release_held(dir *d)
{
    if (d->hlen) {
        put(d, d->held, d->hlen);
        d->hlen = 0;
    }
}

/* A complete frame (ends with 0x00, or an overlong run): decide its fate. */
static void frame_done(dir *d)
{
    uint8_t *f = d->fr;
    size_t n = d->flen;
    d->flen = 0;
    d->frames++;
    if (n <= 1) { /* a lone delimiter: pass it */
        put(d, f, n);
        return;
    }
    /* Every decision is drawn for every frame, in a fixed order, so the
     * fault pattern per frame index does not depend on timing. */
    int drop = chance(d, p_drop), corrupt = chance(d, p_corrupt);
    size_t pos = (size_t)(rnd(d) % (n - 1)); /* never the delimiter */
    unsigned bit = (unsigned)(rnd(d) % 8);
    int dup = chance(d, p_dup), reorder = chance(d, p_reorder);
    if (drop) {
        d->dropped++;
        return;
    }
    if (corrupt) {
        f[pos] ^= (uint8_t)(1u << bit);
        d->corrupted++;
    }
    if (reorder && !d->hlen) {
        memcpy(d->held, f, n);
        d->hlen = n;
        d->held_at = now_ns();
        d->reordered++;
        if (dup) { /* the copy goes out now, the original later */
            put(d, f, n);
            d->duped++;
        }
        return;
    }
    put(d, f, n);
    if (dup) {
        put(d, f, n);
        d->duped++;
    }
    release_held(d); /* this frame overtook the held one */
}

static void take(dir *d, const uint8_t *p, size_t n)
{
    d->bytes_in += n;
    for (size_t k = 0; k < n; k++) {
        d->fr[d->flen++] = p[k];
        if (p[k] == 0 || d->flen == FRAME_MAX)
            frame_done(d);
    }
}

/* Hand the destination everything the line has finished sending. */
static void drain(dir *d, int64_t now)
{
    size_t n = qlen(d);
    if (n && byte_ns) {
        int64_t due = (now - d->line_free) / byte_ns;
        if (due < 0)
            due = 0;
        if ((size_t)due < n)
            n = (size_t)due;
    }
    if (!n)
        return;
    ssize_t w = write(d->to, d->q + d->qh, n);
    if (w <= 0)
        return; /* the reader's side is full: the line waits (as with flow control) */
    d->qh += (size_t)w;
    d->bytes_out += (unsigned long long)w;
    if (byte_ns)
        d->line_free += (int64_t)w * byte_ns;
    if (qlen(d) == 0 && byte_ns == 0)
        d->line_free = now;
}

/* ns until the next byte is due on d's line, or -1 if nothing waits. */
static int64_t next_due(const dir *d, int64_t now)
{
    int64_t t = -1;
    if (qlen(d)) {
        t = byte_ns ? d->line_free + byte_ns - now : 0;
        if (t < 0)
            t = 0;
    }
    if (d->hlen) {
        int64_t h = d->held_at + HOLD_NS - now;
        if (h < 0)
            h = 0;
        if (t < 0 || h < t)
            t = h;
    }
    return t;
}

static int open_side(const char *link, char *name)
{
    int master, slave;
    struct termios t;
    char tmp[600];
    if (openpty(&master, &slave, name, NULL, NULL))
        return -1;
    tcgetattr(slave, &t);
    cfmakeraw(&t);
    tcsetattr(slave, TCSANOW, &t);
    /* The slave stays open here: the master never sees a hang-up between
     * opens, and bytes written before the peer opened are kept. */
    fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
    snprintf(tmp, sizeof tmp, "%s.tmp", link);
    unlink(tmp);
    if (symlink(name, tmp) || rename(tmp, link))
        return -1;
    return master;
}

static void unlink_links(void)
{
    char t[128];
    ssize_t n;
    if (link_a[0] && (n = readlink(link_a, t, sizeof t - 1)) > 0 && (t[n] = 0, !strcmp(t, slave_a)))
        unlink(link_a);
    if (link_b[0] && (n = readlink(link_b, t, sizeof t - 1)) > 0 && (t[n] = 0, !strcmp(t, slave_b)))
        unlink(link_b);
}

static void stats_json(FILE *f, const dir *d)
{
    fprintf(f, "\"%s\": {\"frames\": %llu, \"dropped\": %llu, \"duplicated\": %llu, \"reordered\": %llu, "
               "\"corrupted\": %llu, \"bytes_in\": %llu, \"bytes_out\": %llu}",
            d->name, d->frames, d->dropped, d->duped, d->reordered, d->corrupted, d->bytes_in, d->bytes_out);
}

static double pct_arg(const char *v)
{
    char *end;
    double p = strtod(v, &end);
    if (*end || p < 0 || p > 100) {
        fprintf(stderr, "faultrelay: bad percentage '%s' (0..100)\n", v);
        exit(2);
    }
    return p;
}

int main(int argc, char **argv)
{
    const char *pa = NULL, *pb = NULL, *stats = NULL;
    unsigned long baud = 0;
    unsigned long long seed = 1;
    for (int k = 1; k < argc; k++) {
        const char *a = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        if (!v) {
            fprintf(stderr, "faultrelay: %s needs a value\n", a);
            return 2;
        }
        k++;
        if (!strcmp(a, "--a")) pa = v;
        else if (!strcmp(a, "--b")) pb = v;
        else if (!strcmp(a, "--baud")) baud = strtoul(v, NULL, 10);
        else if (!strcmp(a, "--drop")) p_drop = pct_arg(v);
        else if (!strcmp(a, "--dup")) p_dup = pct_arg(v);
        else if (!strcmp(a, "--reorder")) p_reorder = pct_arg(v);
        else if (!strcmp(a, "--corrupt")) p_corrupt = pct_arg(v);
        else if (!strcmp(a, "--seed")) seed = strtoull(v, NULL, 0);
        else if (!strcmp(a, "--stats")) stats = v;
        else {
            fprintf(stderr, "faultrelay: unknown option %s\n", a);
            return 2;
        }
    }
    if (!pa || !pb) {
        fprintf(stderr, "usage: faultrelay --a PATH --b PATH [--baud B] [--drop PCT] [--dup PCT] "
                        "[--reorder PCT] [--corrupt PCT] [--seed S] [--stats FILE]\n");
        return 2;
    }
    byte_ns = baud ? (int64_t)(10000000000ULL / baud) : 0;
    static dir d[2];
    int ma = open_side(pa, slave_a), mb;
    if (ma >= 0)
        snprintf(link_a, sizeof link_a, "%s", pa);
    mb = open_side(pb, slave_b);
    if (mb >= 0)
        snprintf(link_b, sizeof link_b, "%s", pb);
    atexit(unlink_links);
    if (ma < 0 || mb < 0) {
        perror("faultrelay: pty");
        return 1;
    }
    d[0] = (dir){ .name = "a_to_b", .from = ma, .to = mb, .rng = seed * 0x9E3779B97F4A7C15ULL | 1 };
    d[1] = (dir){ .name = "b_to_a", .from = mb, .to = ma, .rng = (seed + 1) * 0x9E3779B97F4A7C15ULL | 1 };
    for (int k = 0; k < 2; k++) {
        d[k].q = malloc(QCAP);
        if (!d[k].q)
            return 1;
        d[k].line_free = now_ns();
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_sig;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    printf("%s %s\n", slave_a, slave_b);
    fflush(stdout);
    while (!stop) {
        struct pollfd p[2];
        int64_t now = now_ns(), to = -1;
        for (int k = 0; k < 2; k++) {
            int64_t t = next_due(&d[k], now);
            if (t >= 0 && (to < 0 || t < to))
                to = t;
            p[k].fd = d[k].from;
            p[k].events = qlen(&d[k]) < READ_STOP ? POLLIN : 0;
            p[k].revents = 0;
        }
        struct timespec ts = { 0, 0 };
        if (to > 0) {
            ts.tv_sec = (time_t)(to / 1000000000LL);
            ts.tv_nsec = (long)(to % 1000000000LL);
        }
        if (to < 0) {
            ts.tv_sec = 0;
            ts.tv_nsec = 100000000L; /* re-check the stop flag */
        }
        int r = ppoll(p, 2, &ts, NULL);
        if (r < 0 && errno != EINTR)
            return 1;
        for (int k = 0; k < 2; k++) {
            if (p[k].revents & POLLIN) {
                uint8_t buf[4096];
                ssize_t n = read(p[k].fd, buf, sizeof buf);
                if (n > 0)
                    take(&d[k], buf, (size_t)n);
            } else if (p[k].revents & (POLLHUP | POLLERR)) {
                struct timespec nap = { 0, 1000000L }; /* slave closed: no spin */
                nanosleep(&nap, NULL);
            }
        }
        now = now_ns();
        for (int k = 0; k < 2; k++) {
            if (d[k].hlen && now - d[k].held_at >= HOLD_NS)
                release_held(&d[k]);
            drain(&d[k], now);
        }
    }
    if (stats) {
        FILE *f = fopen(stats, "w");
        if (f) {
            fprintf(f, "{");
            stats_json(f, &d[0]);
            fprintf(f, ", ");
            stats_json(f, &d[1]);
            fprintf(f, "}\n");
            fclose(f);
        }
    }
    return 0;
}
