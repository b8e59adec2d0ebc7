/*
 * it2n-instrument: example instrument streaming a grid data set with the
 * it2n serial protocol. Everything below main() is the POSIX "edge" (fd
 * streams, options, CSV file); session.c and synth.c are MCU-shaped.
 *
 * usage: it2n-instrument [--device PATH] [--model ID] [--degree N[xM]]
 *        [--seed S] [--csv FILE] [--type1] [--z] [--chord]
 *        [--rto MS] [--tries N] [--timeout S] [--quiet]
 * Without --device the frames go to stdout once each (one-way, no ACKs).
 */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "session.h"
#include "synth.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: it2n-instrument [--device PATH] [--model ID] [--degree N[xM]] [--seed S]\n"
            "                       [--csv FILE] [--type1] [--z] [--chord]\n"
            "                       [--rto MS] [--tries N] [--timeout S] [--quiet]\n"
            "  --device PATH  tty/pty (or any fd-like path) to talk to it2nd, reliable mode;\n"
            "                 without it, frames are written once to stdout (no ACKs)\n"
            "  --model ID     model id 0..254 (default 0)\n"
            "  --degree NxM   grid degrees 1..%d (default 3x3)\n"
            "  --seed S       synthetic data seed (default 1)\n"
            "  --csv FILE     send FILE (header i,j,footprint,x,y[,z],T,I,F) instead\n"
            "exit: 0 all ACKed, 1 NACKed, 2 usage/data error, 3 I/O error or timeout\n",
            IT2N_MAX_DEGREE);
}

/* ---- fd streams (the only OS-specific part) ---------------------------- */

typedef struct fd_state {
    int fd;
    int err; /* errno of the last failure, 0 = end of stream */
} fd_state;

static int fd_write(it2n_ostream *s, const uint8_t *buf, size_t len)
{
    fd_state *f = s->state;
    while (len > 0) {
        ssize_t n = write(f->fd, buf, len);
        if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
            struct pollfd p = {f->fd, POLLOUT, 0};
            if (poll(&p, 1, 1000) <= 0)
                return -1; /* peer not draining: frame lost, retried later */
            continue;
        }
        if (n <= 0)
            return -1;
        buf += n;
        len -= (size_t)n;
    }
    return 0;
}

static int fd_read(it2n_istream *s, uint8_t *buf, size_t len)
{
    fd_state *f = s->state;
    ssize_t n = read(f->fd, buf, len);
    if (n < 0 && (errno == EAGAIN || errno == EINTR))
        return 0;
    if (n <= 0) {
        f->err = n < 0 ? errno : 0;
        return -1; /* error or end of stream */
    }
    return (int)n;
}

static uint32_t now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint32_t)((uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u);
}

static int open_device(const char *path)
{
    int fd = open(path, O_RDWR | O_NOCTTY | O_NONBLOCK);
    struct termios t;
    if (fd < 0) {
        fprintf(stderr, "it2n-instrument: cannot open %s: %s\n", path, strerror(errno));
        return -1;
    }
    if (isatty(fd) && tcgetattr(fd, &t) == 0) {
        cfmakeraw(&t);
        cfsetispeed(&t, B115200);
        cfsetospeed(&t, B115200);
        t.c_cc[VMIN] = 1; /* with O_NONBLOCK: EAGAIN, not 0, when idle */
        t.c_cc[VTIME] = 0;
        tcsetattr(fd, TCSANOW, &t);
    }
    return fd;
}

/* ---- CSV input ----------------------------------------------------------- */

/* Split a line at commas in place; returns the field count (<= max). */
static int split(char *line, char **f, int max)
{
    int n = 0;
    char *p = line;
    while (n < max) {
        f[n++] = p;
        p = strchr(p, ',');
        if (p == NULL)
            break;
        *p++ = '\0';
    }
    for (int k = 0; k < n; k++) /* trim trailing newline / spaces */
        for (size_t l = strlen(f[k]); l > 0 && strchr(" \r\n\t", f[k][l - 1]); l--)
            f[k][l - 1] = '\0';
    return n;
}

static int load_csv(const char *path, it2n_dataset *ds, unsigned extra_flags)
{
    enum { MAXROWS = IT2N_DIM * IT2N_DIM * IT2N_FP_COUNT };
    static struct row {
        unsigned i, j, fp;
        it2n_val v[IT2N_CH_COUNT];
    } rows[MAXROWS];
    char line[512], *f[10];
    unsigned nrows = 0, n = 0, m = 0, lineno = 0, fpmask = 0;
    int has_z, cols;
    it2n_errinfo err;
    FILE *in = fopen(path, "r");

    if (in == NULL) {
        fprintf(stderr, "it2n-instrument: cannot open %s: %s\n", path, strerror(errno));
        return -1;
    }
    do { /* skip leading comments */
        if (fgets(line, sizeof line, in) == NULL)
            line[0] = '\0';
        else
            lineno++;
    } while (line[0] == '#');
    lineno--;
    if (line[0] == '\0') {
        fprintf(stderr, "%s: no header line\n", path);
        fclose(in);
        return -1;
    }
    cols = split(line, f, 10);
    has_z = cols == 9 && strcmp(f[5], "z") == 0;
    if (!(cols == 8 || has_z) || strcmp(f[0], "i") || strcmp(f[2], "footprint")) {
        fprintf(stderr, "%s:%u: header must be i,j,footprint,x,y[,z],T,I,F\n", path, lineno);
        fclose(in);
        return -1;
    }
    while (fgets(line, sizeof line, in) != NULL) {
        struct row *r = &rows[nrows];
        lineno++;
        if (line[0] == '\n' || line[0] == '#')
            continue;
        if (nrows == MAXROWS || split(line, f, 10) != cols) {
            fprintf(stderr, "%s:%u: %s\n", path, lineno, nrows == MAXROWS ? "too many rows" : "wrong number of fields");
            fclose(in);
            return -1;
        }
        char *end;
        unsigned long ii = strtoul(f[0], &end, 10), jj = strtoul(f[1], &end, 10);
        int fp = it2n_fp_from_name(f[2], strlen(f[2]));
        if (ii > IT2N_MAX_DEGREE || jj > IT2N_MAX_DEGREE || fp < 0) {
            fprintf(stderr, "%s:%u: bad index or footprint (i, j <= %d; LL..RR)\n", path, lineno, IT2N_MAX_DEGREE);
            fclose(in);
            return -1;
        }
        r->i = (unsigned)ii;
        r->j = (unsigned)jj;
        r->fp = (unsigned)fp;
        memset(r->v, 0, sizeof r->v);
        static const int chx[2][6] = {{IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F, -1},
                                      {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_Z, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F}};
        for (int c = 3; c < cols; c++) {
            int ch = chx[has_z][c - 3];
            if (it2n_parse_val(f[c], strlen(f[c]), &r->v[ch]) != IT2N_OK) {
                fprintf(stderr, "%s:%u: field %d (%s) is not a number in range: '%s'\n", path, lineno, c + 1,
                        it2n_ch_name((unsigned)ch), f[c]);
                fclose(in);
                return -1;
            }
        }
        if (r->i > n)
            n = r->i;
        if (r->j > m)
            m = r->j;
        fpmask |= 1u << r->fp;
        nrows++;
    }
    fclose(in);
    unsigned flags = extra_flags | (has_z ? IT2N_F_Z : 0u) | (fpmask == (1u << IT2N_FP_D) ? IT2N_F_TYPE1 : 0u);
    if (it2n_dataset_init(ds, n, m, flags, &err) != IT2N_OK) {
        fprintf(stderr, "%s: grid %ux%u not accepted: %s\n", path, n, m, it2n_strerror(err.code));
        return -1;
    }
    for (unsigned k = 0; k < nrows; k++) {
        if (it2n_dataset_put(ds, rows[k].i, rows[k].j, rows[k].fp, rows[k].v, false, &err) != IT2N_OK) {
            fprintf(stderr, "%s: row %u (%u,%u,%s): %s (channel %s)\n", path, k + 2, rows[k].i, rows[k].j,
                    it2n_fp_name(rows[k].fp), it2n_strerror(err.code),
                    err.ch >= 0 ? it2n_ch_name((unsigned)err.ch) : "-");
            return -1;
        }
    }
    if (it2n_dataset_check(ds, &err) != IT2N_OK) {
        fprintf(stderr, "%s: data set invalid at (%d,%d) %s: %s\n", path, err.i, err.j,
                err.fp >= 0 ? it2n_fp_name((unsigned)err.fp) : "-", it2n_strerror(err.code));
        return -1;
    }
    return 0;
}

/* ---- main ---------------------------------------------------------------- */

static int parse_uint(const char *s, unsigned long max, unsigned long *out)
{
    char *end;
    errno = 0;
    *out = strtoul(s, &end, 10);
    return errno == 0 && end != s && *end == '\0' && *out <= max && s[0] != '-';
}

int main(int argc, char **argv)
{
    static it2n_dataset ds;
    static session sess;
    const char *device = NULL, *csv = NULL;
    unsigned long model = 0, n = 3, m = 3, seed = 1, rto = 200, tries = 10, timeout = 60;
    unsigned flags = 0;
    int quiet = 0;

    for (int k = 1; k < argc; k++) {
        const char *a = argv[k], *v = k + 1 < argc ? argv[k + 1] : NULL;
        int ok = 1;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--type1")) {
            flags |= IT2N_F_TYPE1;
        } else if (!strcmp(a, "--z")) {
            flags |= IT2N_F_Z;
        } else if (!strcmp(a, "--chord")) {
            flags |= IT2N_F_CHORD;
        } else if (!strcmp(a, "--quiet")) {
            quiet = 1;
        } else if (v == NULL) {
            ok = 0;
        } else if (!strcmp(a, "--device")) {
            device = v, k++;
        } else if (!strcmp(a, "--csv")) {
            csv = v, k++;
        } else if (!strcmp(a, "--model")) {
            ok = parse_uint(v, 254, &model), k++;
        } else if (!strcmp(a, "--seed")) {
            ok = parse_uint(v, UINT32_MAX, &seed), k++;
        } else if (!strcmp(a, "--rto")) {
            ok = parse_uint(v, 600000, &rto) && rto > 0, k++;
        } else if (!strcmp(a, "--tries")) {
            ok = parse_uint(v, 255, &tries) && tries > 0, k++;
        } else if (!strcmp(a, "--timeout")) {
            ok = parse_uint(v, 86400, &timeout), k++;
        } else if (!strcmp(a, "--degree")) {
            char buf[32], *x;
            snprintf(buf, sizeof buf, "%s", v);
            x = strchr(buf, 'x');
            if (x != NULL)
                *x = '\0';
            ok = parse_uint(buf, IT2N_MAX_DEGREE, &n) && n >= 1;
            m = n;
            if (ok && x != NULL)
                ok = parse_uint(x + 1, IT2N_MAX_DEGREE, &m) && m >= 1;
            k++;
        } else {
            ok = 0;
        }
        if (!ok) {
            fprintf(stderr, "it2n-instrument: bad or incomplete option '%s'%s%s\n", a, v ? " " : "", v ? v : "");
            usage(stderr);
            return 2;
        }
    }

    it2n_errinfo err;
    if (csv != NULL) {
        if (load_csv(csv, &ds, flags & IT2N_F_CHORD) != 0)
            return 2;
    } else if (synth_dataset(&ds, (unsigned)n, (unsigned)m, flags, (uint32_t)seed, &err) != IT2N_OK) {
        fprintf(stderr, "it2n-instrument: synthetic data set refused: %s\n", it2n_strerror(err.code));
        return 2;
    }

    fd_state ofd = {STDOUT_FILENO, 0}, ifd = {STDIN_FILENO, 0};
    if (device != NULL) {
        ofd.fd = ifd.fd = open_device(device);
        if (ofd.fd < 0)
            return 3;
    }
    it2n_ostream os = {fd_write, &ofd};
    it2n_istream is = {fd_read, &ifd};
    uint32_t t0 = now_ms();
    /* A random first sequence number, and a session id for the one-way
     * mode (v1.1); with --device the daemon hands out the session (v1.2). */
    uint32_t rnd[2] = {t0 ^ (uint32_t)getpid(), (t0 ^ (uint32_t)getpid()) * 2654435761u};
    if (getrandom(rnd, sizeof rnd, GRND_NONBLOCK) != (ssize_t)sizeof rnd)
        rnd[0] ^= (uint32_t)time(NULL);
    if (session_init(&sess, &ds, (uint8_t)model, &os, &is, (uint32_t)rto, (uint8_t)tries, device == NULL,
                     (uint16_t)rnd[1], rnd[0] ? rnd[0] : 1u) != IT2N_OK)
        return 2;
    int st;
    for (;;) {
        uint32_t now = now_ms();
        st = session_step(&sess, now);
        if (st != SESSION_RUNNING)
            break;
        if (timeout > 0 && now - t0 > timeout * 1000u) {
            fprintf(stderr, "it2n-instrument: gave up after %lu s\n", timeout);
            return 3;
        }
        struct pollfd p = {ifd.fd, POLLIN, 0};
        (void)poll(&p, 1, (int)session_idle_ms(&sess, now));
    }
    if (st == SESSION_FAILED) {
        if (sess.fail_code == IT2N_PROTO_ERR_TIMEOUT || sess.fail_code == IT2N_PROTO_ERR_STREAM) {
            if (sess.fail_code == IT2N_PROTO_ERR_STREAM)
                fprintf(stderr, "it2n-instrument: reading %s: %s\n", device ? device : "stdin",
                        ifd.err ? strerror(ifd.err) : "end of stream");
            else
                fprintf(stderr, "it2n-instrument: %s (%s seq %u)\n", it2n_proto_strerror(sess.fail_code),
                        it2n_msg_name(sess.fail_type) ? it2n_msg_name(sess.fail_type) : "-", sess.fail_seq);
            return 3;
        }
        const it2n_msg_nack *k = &sess.nack;
        fprintf(stderr,
                "it2n-instrument: %s seq %u refused: %s (code %d) at point (%d,%d) "
                "footprint %s channel %s\n",
                it2n_msg_name(sess.fail_type) ? it2n_msg_name(sess.fail_type) : "?", sess.fail_seq,
                sess.fail_code <= -100 ? it2n_proto_strerror(sess.fail_code) : it2n_strerror(sess.fail_code),
                sess.fail_code, k->i, k->j, k->fp >= 0 ? it2n_fp_name((unsigned)k->fp) : "-",
                k->ch >= 0 ? it2n_ch_name((unsigned)k->ch) : "-");
        return 1;
    }
    if (!quiet)
        fprintf(stderr,
                "it2n-instrument: model %lu (%ux%u, flags 0x%x): %u entries in %u PUTs %s; "
                "%u retransmissions\n",
                model, ds.n, ds.m, ds.flags, sess.entries, sess.puts, device ? "acknowledged" : "written",
                sess.link.stats.tx_retx);
    return 0;
}
