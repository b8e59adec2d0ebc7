/*
 * ptybridge — a null-modem cable made of two pty pairs, for RTU and link
 * tests without hardware: bytes written to one slave come out of the other.
 * Prints "SLAVE_A SLAVE_B" on stdout, then relays until SIGTERM.
 * While a side's slave is closed its master reports hang-up; the relay then
 * naps 10 ms instead of spinning.
 */
#include <errno.h>
#include <poll.h>
#include <pty.h>
#include <stdio.h>
#include <termios.h>
#include <unistd.h>

static int open_side(char *name)
{
    int master, slave;
    struct termios t;
    if (openpty(&master, &slave, name, NULL, NULL))
        return -1;
    tcgetattr(slave, &t);
    cfmakeraw(&t);
    tcsetattr(slave, TCSANOW, &t);
    /* Keep the slave open here too, so the master never sees a hang-up
     * between clients (and bytes written early are kept). */
    return master;
}

int main(void)
{
    char a[128], b[128];
    int ma = open_side(a), mb = open_side(b);
    if (ma < 0 || mb < 0) {
        perror("openpty");
        return 1;
    }
    printf("%s %s\n", a, b);
    fflush(stdout);
    for (;;) {
        struct pollfd p[2] = { { ma, POLLIN, 0 }, { mb, POLLIN, 0 } };
        char buf[4096];
        if (poll(p, 2, -1) < 0 && errno != EINTR)
            return 1;
        for (int k = 0; k < 2; k++) {
            if (p[k].revents & POLLIN) {
                ssize_t n = read(p[k].fd, buf, sizeof buf);
                if (n > 0 && write(p[1 - k].fd, buf, (size_t)n) != n)
                    usleep(1000);
            } else if (p[k].revents) {
                usleep(10000);
            }
        }
    }
}
