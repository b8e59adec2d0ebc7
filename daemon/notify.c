/* notify.c — see notify.h. */
#include "notify.h"

#include <errno.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "log.h"

static struct sockaddr_un addr;
static socklen_t addr_len;
static uint64_t wd_ms;

int notify_init(void)
{
    const char *path = getenv("NOTIFY_SOCKET");
    const char *wd = getenv("WATCHDOG_USEC");
    size_t len;
    addr_len = 0;
    wd_ms = 0;
    if (wd) {
        const char *pid = getenv("WATCHDOG_PID");
        if (!pid || strtol(pid, NULL, 10) == (long)getpid())
            wd_ms = strtoull(wd, NULL, 10) / 1000u;
    }
    if (!path || !*path)
        return 0;
    len = strlen(path);
    if ((path[0] != '/' && path[0] != '@') || len >= sizeof addr.sun_path) {
        log_warn("NOTIFY_SOCKET '%s' unusable; notifications disabled", path);
        return -1;
    }
    memset(&addr, 0, sizeof addr);
    addr.sun_family = AF_UNIX;
    memcpy(addr.sun_path, path, len);
    if (path[0] == '@')
        addr.sun_path[0] = '\0';
    addr_len = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + len);
    return 0;
}

int notify_send(const char *state)
{
    int fd, rc = 0;
    if (addr_len == 0)
        return 0;
    fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    if (sendto(fd, state, strlen(state), MSG_NOSIGNAL, (struct sockaddr *)&addr, addr_len) < 0) {
        log_debug("notify: %s", strerror(errno));
        rc = -1;
    }
    close(fd);
    return rc;
}

uint64_t notify_watchdog_ms(void)
{
    return wd_ms;
}
