/* fc23_bare — the baseline of the FC 23 benchmark: a bare libmodbus
 * server answering FC 23 of the same sizes as it2nd's query (write 2
 * registers at 64, read 108 at 128) from a modbus_mapping_t, in a poll()
 * multi-client loop (one process, one thread; a readable client is read
 * with one recv() into its buffer, every complete ADU, framed by the MBAP
 * length, is answered with modbus_reply()): libmodbus used as carefully as
 * it allows. it2nd's own loop (daemon/loop.c) moves the same bytes through
 * io_uring where the kernel allows it. With "receive" as second argument each readable client
 * is read with libmodbus' own modbus_receive() instead (select + a recv
 * per header/body step: slower; an informational second baseline).
 *
 * The read registers hold a fixed pattern (0x5A00 + 7 r, fc23_load.c
 * checks it). Listens on 127.0.0.1, port 0 = any free port; prints
 * "port N" on stdout once listening, runs until SIGTERM/SIGINT. */
#include <errno.h>
#include <fcntl.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>
#include <arpa/inet.h>

#define MAXFD 300

struct cbuf {
    uint8_t b[MODBUS_TCP_MAX_ADU_LENGTH * 2];
    size_t len;
};
static struct cbuf bufs[MAXFD];

/* it2nd's way: one recv, then every complete ADU. 0, or -1: close. */
static int serve_framed(modbus_t *ctx, modbus_mapping_t *map, int fd, struct cbuf *c)
{
    ssize_t r = recv(fd, c->b + c->len, sizeof c->b - c->len, 0);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EINTR))
        return -1;
    if (r < 0)
        return 0;
    c->len += (size_t)r;
    while (c->len >= 7) {
        size_t total = 6u + ((size_t)c->b[4] << 8 | c->b[5]);
        if (total > MODBUS_TCP_MAX_ADU_LENGTH || total < 8)
            return -1;
        if (c->len < total)
            break;
        if (modbus_reply(ctx, c->b, (int)total, map) < 0)
            return -1;
        memmove(c->b, c->b + total, c->len - total);
        c->len -= total;
    }
    return 0;
}

static volatile sig_atomic_t quit;

static void on_signal(int sig)
{
    (void)sig;
    quit = 1;
}

int main(int argc, char **argv)
{
    int port = argc > 1 ? atoi(argv[1]) : 0;
    int use_receive = argc > 2 && !strcmp(argv[2], "receive");
    struct pollfd pfd[MAXFD];
    int nfd = 1;
    uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    modbus_t *ctx = modbus_new_tcp("127.0.0.1", port);
    modbus_mapping_t *map = modbus_mapping_new(0, 0, 10000, 10000);
    int lfd = socket(AF_INET, SOCK_STREAM, 0), one = 1;

    if (!ctx || !map || lfd < 0)
        return 1;
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGPIPE, SIG_IGN);
    for (int r = 0; r < 108; r++)
        map->tab_registers[128 + r] = (uint16_t)(0x5A00u + (unsigned)r * 7u);
    modbus_set_slave(ctx, 1);
    setsockopt(lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    memset(&sa, 0, sizeof sa);
    sa.sin_family = AF_INET;
    sa.sin_port = htons((uint16_t)port);
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (bind(lfd, (struct sockaddr *)&sa, sizeof sa) < 0 || listen(lfd, 64) < 0 ||
        getsockname(lfd, (struct sockaddr *)&sa, &sl) < 0) {
        perror("fc23_bare: listen");
        return 1;
    }
    printf("port %u\n", ntohs(sa.sin_port));
    fflush(stdout);
    pfd[0].fd = lfd;
    pfd[0].events = POLLIN;
    while (!quit) {
        int n = poll(pfd, (nfds_t)nfd, 500);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            break;
        }
        if (pfd[0].revents & POLLIN) {
            int c = accept(lfd, NULL, NULL);
            if (c >= 0) {
                if (nfd < MAXFD) {
                    setsockopt(c, IPPROTO_TCP, 1 /* TCP_NODELAY */, &one, sizeof one);
                    pfd[nfd].fd = c;
                    pfd[nfd].events = POLLIN;
                    pfd[nfd].revents = 0;
                    bufs[nfd].len = 0;
                    if (!use_receive)
                        fcntl(c, F_SETFL, fcntl(c, F_GETFL) | O_NONBLOCK);
                    nfd++;
                } else {
                    close(c);
                }
            }
        }
        for (int k = 1; k < nfd; k++) {
            if (!pfd[k].revents)
                continue;
            int rc;
            modbus_set_socket(ctx, pfd[k].fd);
            if (use_receive) {
                rc = modbus_receive(ctx, query);
                if (rc > 0)
                    rc = modbus_reply(ctx, query, rc, map);
                if (rc == 0 && (pfd[k].revents & (POLLERR | POLLHUP | POLLNVAL)))
                    rc = -1;
            } else {
                rc = serve_framed(ctx, map, pfd[k].fd, &bufs[k]);
            }
            if (rc < 0) {
                close(pfd[k].fd);
                --nfd;
                pfd[k] = pfd[nfd];
                bufs[k] = bufs[nfd];
                k--;
            }
        }
    }
    for (int k = 1; k < nfd; k++)
        close(pfd[k].fd);
    close(lfd);
    modbus_mapping_free(map);
    modbus_free(ctx);
    return 0;
}
