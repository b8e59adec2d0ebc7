/* link_serial.c — see link_serial.h. */
#include "link_serial.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/file.h>
#include <termios.h>
#include <unistd.h>

static speed_t speed_of(int baud)
{
    switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    case 1000000: return B1000000;
    case 2000000: return B2000000;
    case 3000000: return B3000000;
    case 4000000: return B4000000;
    default: return 0;
    }
}

int link_serial_lock(int fd)
{
    if (flock(fd, LOCK_EX | LOCK_NB) == 0)
        return 0;
    if (errno == EWOULDBLOCK)
        errno = EBUSY; /* "in use" */
    return -1;
}

int link_serial_open(const char *device, int baud)
{
    struct termios t;
    speed_t sp = speed_of(baud);
    int fd;
    if (!sp) {
        errno = EINVAL;
        return -1;
    }
    fd = open(device, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return -1;
    /* A second it2nd, or one whose vanished pty path now names another
     * process's pty, must neither steal frames nor change the line
     * settings. */
    if (link_serial_lock(fd)) {
        int e = errno;
        close(fd);
        errno = e;
        return -1;
    }
    if (tcgetattr(fd, &t) == 0) {
        cfmakeraw(&t);
        t.c_cflag |= CLOCAL | CREAD;
        t.c_cc[VMIN] = 0;
        t.c_cc[VTIME] = 0;
        cfsetispeed(&t, sp);
        cfsetospeed(&t, sp);
        if (tcsetattr(fd, TCSANOW, &t)) {
            int e = errno;
            close(fd);
            errno = e;
            return -1;
        }
        tcflush(fd, TCIFLUSH);
    }
    /* Not a tty (a FIFO or socket in tests): used as is. */
    return fd;
}
