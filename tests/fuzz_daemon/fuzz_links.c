/* Fuzz target "links": arbitrary bytes from an instrument on a serial link
 * into the daemon's link handler (daemon/links.c: protocol/ receiver,
 * HELLO, CONFIGURE, PUT batches, COMMIT, RESET, QUERY, LOCATE, SAMPLE and
 * GET_NET response runs, EVENTs, ACK after the WAL commit) with model 1
 * (the paper's data set, solved) and model 2 (type-1 2x2, empty).
 *
 * The link is opened the daemon's way (link_serial_open on a pty), then a
 * socket is dup2()ed over its fd for the input; the daemon's write()s to
 * it are taken by __wrap_write (linked with -Wl,--wrap=write) into a
 * buffer that models the tty's output room: 4 KiB (a UART transmit
 * buffer, emptied between loop iterations; the daemon then gets POLLOUT if
 * it asked for it). USB is stubbed out. Input: byte 0 bit 0
 * the WAL append fails, bit 1 the group commit fails, bit 2 the harness
 * does not ACK the daemon's reliable frames; then items
 * [kind][len][len bytes]: kind bit 7 set: the bytes go out raw (noise);
 * else they are the payload of a frame the harness encodes with a valid
 * CRC: type = kind & 0x3F, bit 6 reliable (sequence numbers counted here,
 * the first one with SYN). Between items the daemon's loop is simulated:
 * read handler, group commit (models_pass_end with EVENTs, links_release),
 * and a little time for the link's poll timer.
 * Invariants: no crash/UB/leak; everything the daemon sends decodes as
 * frames with a valid CRC whose payload unpacks (what the daemon sends is
 * well-formed); after any input every SOLVED model is consistent with a
 * fresh solve of its data (fuzz_model_check.h). */
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
#include "fuzz_model_check.h"
#include "it2n_link.h"
#include "link_usb.h"
#include "links.h"
#include "models.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* ---- USB stubs: only a serial link is configured ---- */
int link_usb_init(void) { return 0; }
void link_usb_free(void) {}
void link_usb_on_arrival(void (*fn)(void *arg), void *arg) { (void)fn; (void)arg; }
struct usb_link *link_usb_open(const struct conf_link *c, usb_rx_fn rx, usb_gone_fn gone, void *arg)
{
    (void)c; (void)rx; (void)gone; (void)arg;
    return NULL;
}
int link_usb_write(struct usb_link *u, const uint8_t *buf, size_t len) { (void)u; (void)buf; (void)len; return -1; }
void link_usb_close(struct usb_link *u) { (void)u; }
int link_usb_match(const struct conf_link *c, uint16_t vid, uint16_t pid) { (void)c; (void)vid; (void)pid; return 0; }
int link_usb_count(const struct conf_link *c) { (void)c; return 0; }

/* ---- the link's output side ---- */
ssize_t __real_write(int fd, const void *buf, size_t n);
ssize_t __wrap_write(int fd, const void *buf, size_t n);

/* A UART transmit buffer: full after 4 KiB until the next loop iteration
 * (a SAMPLE run overflows it; security finding 7). */
#define TTY_ROOM 4096u
static uint8_t out[1 << 21];
static size_t got, room_used;
static int link_fd = -1;

ssize_t __wrap_write(int fd, const void *buf, size_t n)
{
    if (fd != link_fd)
        return __real_write(fd, buf, n);
    size_t k = TTY_ROOM - room_used < n ? TTY_ROOM - room_used : n;
    if (k == 0 || got + k > sizeof out) {
        errno = EAGAIN;
        return -1;
    }
    memcpy(out + got, buf, k);
    got += k;
    room_used += k;
    return (ssize_t)k;
}

/* The UART sent what was queued (between loop iterations). */
static void tty_drained(void)
{
    room_used = 0;
}

#define NMODELS FUZZ_STANDARD_MODELS
static struct model *pristine[NMODELS]; /* models_dup copies */
static struct conf link_conf;
static int journal_fails, commit_fails;

static int journal(void *arg, const struct model_rec *rec)
{
    (void)arg;
    (void)rec;
    return journal_fails ? -1 : 0;
}

static void changed(void *arg, const struct model *md, int old_state, uint32_t old_gen)
{
    (void)arg;
    (void)old_gen;
    links_event(md, old_state);
}

static void commit_pass(void)
{
    int ok = !commit_fails;
    models_pass_end(ok, changed, NULL);
    links_release(ok);
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    char name[64];
    int master, slave;
    (void)argc;
    (void)argv;
    fuzz_standard_models(4);
    for (int k = 0; k < NMODELS; k++)
        pristine[k] = models_dup(models_at(k));
    models_set_journal(journal, NULL);
    /* The pty stays open (master kept) so the device can be reopened. */
    fuzz_check(openpty(&master, &slave, name, NULL, NULL) == 0, "openpty");
    close(slave);
    memset(&link_conf, 0, sizeof link_conf);
    link_conf.nlinks = 1;
    link_conf.link_backoff_max = 30;
    snprintf(link_conf.link[0].name, sizeof link_conf.link[0].name, "fuzz");
    snprintf(link_conf.link[0].device, sizeof link_conf.link[0].device, "%s", name);
    link_conf.link[0].type = CONF_LINK_SERIAL;
    link_conf.link[0].baud = 115200;
    return 0;
}

static void pump(int fd)
{
    for (int guard = 0; guard < 10000; guard++) {
        int avail = 0;
        commit_pass();
        if (!fake_fd_find(fd))
            return;
        fuzz_check(ioctl(fd, FIONREAD, &avail) == 0, "FIONREAD");
        if (avail == 0)
            return;
        fake_fd_dispatch(fd, POLLIN);
    }
    fuzz_check(0, "link makes progress");
}

/* Everything the daemon sent: frames with valid CRCs whose payloads
 * unpack. Reliable ones are ACKed (unless the input says the peer stays
 * silent), so response runs (SAMPLE, GET_NET) and EVENTs flow. Returns
 * the number of ACKs sent. */
static it2n_frame_decoder out_dec;
static size_t checked;
static int peer_acks;

static unsigned process_output(int line)
{
    static it2n_msg msg;
    static uint8_t ack_wire[64];
    unsigned acks = 0;
    while (checked < got) {
        it2n_frame_hdr h;
        const uint8_t *p = NULL;
        size_t used = 0;
        int r = it2n_frame_decode(&out_dec, out + checked, got - checked, &used, &h, &p);
        fuzz_note("daemon output at %zu: decode %d", checked, r);
        if (r < 0 && getenv("IT2N_FUZZ_DUMP")) {
            FILE *df = fopen(getenv("IT2N_FUZZ_DUMP"), "wb");
            if (df) {
                fwrite(out, 1, got, df);
                fclose(df);
            }
        }
        fuzz_check(r >= 0, "daemon output frames decode");
        checked += used;
        if (r != 1)
            continue;
        it2n_proto_errinfo e;
        fuzz_note("daemon frame type 0x%02x len %u", h.type, h.len);
        size_t sess = (h.flags & IT2N_FLAG_SYN) ? IT2N_FRAME_SESSION_SIZE : 0; /* v1.1 SYN: session id */
        fuzz_check(h.len >= sess && it2n_msg_unpack(h.type, p + sess, h.len - sess, &msg, &e) == IT2N_OK,
                   "daemon frames unpack");
        if ((h.flags & IT2N_FLAG_REL) && peer_acks) {
            uint8_t pl[8];
            memset(&msg, 0, sizeof msg);
            msg.type = IT2N_MSG_ACK;
            msg.u.ack.seq = h.seq;
            int n = it2n_msg_pack(&msg, pl, sizeof pl, NULL);
            it2n_frame_hdr ah = { IT2N_PROTO_VERSION, IT2N_MSG_ACK, 0, 0, (uint16_t)n };
            int w = it2n_frame_encode(&ah, pl, (size_t)n, ack_wire, sizeof ack_wire);
            fuzz_check(n > 0 && w > 0 && write(line, ack_wire, (size_t)w) == w, "harness ACK");
            acks++;
        }
    }
    return acks;
}

/* Loop iterations until the link is quiet, at most 16 (a SAMPLE run of
 * 65536 nodes is not played out in full: bounded time per input). */
static void serve(int fd, int line)
{
    for (int k = 0; k < 16; k++) {
        const struct fake_fd *f;
        pump(fd);
        tty_drained();
        if ((f = fake_fd_find(fd)) != NULL && (f->events & POLLOUT))
            fake_fd_dispatch(fd, POLLOUT);
        if (process_output(line) == 0)
            return;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static uint8_t wire[IT2N_FRAME_MAX_WIRE];
    size_t pos = 1;
    uint16_t seq = 0;
    int sp[2], first = 1;
    if (size < 1 || size > 8192)
        return 0;
    journal_fails = data[0] & 1;
    commit_fails = (data[0] >> 1) & 1;
    for (int k = 0; k < NMODELS; k++)
        models_copy(models_at(k), pristine[k]);

    fake_reset();
    fuzz_check(links_start(&link_conf) == 0 && fake_fd_last() != NULL, "links_start opens the link");
    int fd = fake_fd_last()->fd;
    got = 0;
    checked = 0;
    room_used = 0;
    link_fd = fd;
    peer_acks = !(data[0] & 4);
    it2n_frame_decoder_init(&out_dec);
    fuzz_check(socketpair(AF_UNIX, SOCK_STREAM, 0, sp) == 0, "socketpair");
    fuzz_check(fcntl(sp[0], F_SETFL, O_NONBLOCK) == 0 && fcntl(sp[1], F_SETFL, O_NONBLOCK) == 0, "O_NONBLOCK");
    fuzz_check(dup2(sp[0], fd) == fd, "dup2");
    close(sp[0]);
    int line = sp[1];
    fake_advance(150); /* poll timer: our HELLO goes out on the new fd */

    while (pos + 2 <= size && fake_fd_find(fd)) {
        uint8_t kind = data[pos], len = data[pos + 1];
        pos += 2;
        if (len > size - pos)
            len = (uint8_t)(size - pos);
        if (kind & 0x80u) {
            fuzz_check(write(line, data + pos, len) == len, "harness write");
        } else {
            static uint8_t pl[4 + 256];
            size_t sess = 0;
            it2n_frame_hdr h = { IT2N_PROTO_VERSION, (uint8_t)(kind & 0x3Fu), 0, 0, len };
            if (kind & 0x40u) {
                h.flags = IT2N_FLAG_REL | (first ? IT2N_FLAG_SYN : 0);
                h.seq = seq++;
                if (first) { /* v1.1: a SYN frame starts with the session id */
                    memcpy(pl, "\x55\x5e\x11\x00", 4);
                    sess = 4;
                }
                first = 0;
            }
            memcpy(pl + sess, data + pos, len);
            h.len = (uint16_t)(len + sess);
            int w = it2n_frame_encode(&h, pl, len + sess, wire, sizeof wire);
            fuzz_check(w > 0, "harness frame encode");
            fuzz_check(write(line, wire, (size_t)w) == w, "harness write");
        }
        pos += len;
        serve(fd, line);
        fake_advance(20);
        serve(fd, line);
    }
    /* Let retransmissions and response runs play out. */
    for (int k = 0; k < 8 && fake_fd_find(fd); k++) {
        fake_advance(100);
        serve(fd, line);
    }
    process_output(line);
    if (getenv("IT2N_FUZZ_VERBOSE"))
        fprintf(stderr, "links: %zu bytes out, model 1 state %d gen %u, model 2 state %d gen %u\n", got,
                models_at(0)->state, models_at(0)->gen, models_at(1)->state, models_at(1)->gen);
    for (int k = 0; k < NMODELS; k++)
        fuzz_check_model(models_at(k));
    links_stop();
    link_fd = -1;
    close(line);
    (void)fake_log_errors();
    return 0;
}
