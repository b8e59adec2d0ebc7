/* log.c — see log.h. */
#include "log.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

enum sink { SINK_STDERR, SINK_JOURNAL, SINK_SYSLOG };

static enum sink sink = SINK_STDERR;
static int max_prio = LOG_NOTICE;
static int starting = 1;

#ifndef _PATH_LOG
#define _PATH_LOG "/dev/log"
#endif

/* Is there a syslog daemon listening? (syslog(3) drops messages silently
 * when there is none, so a fatal start-up error would print nothing.) */
static int syslog_reachable(void)
{
    struct sockaddr_un sa;
    int ok = 0;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", _PATH_LOG);
    for (int type = SOCK_DGRAM; !ok && type; type = type == SOCK_DGRAM ? SOCK_STREAM : 0) {
        int fd = socket(AF_UNIX, type | SOCK_CLOEXEC, 0);
        if (fd < 0)
            continue;
        ok = connect(fd, (const struct sockaddr *)&sa, sizeof sa) == 0;
        close(fd);
    }
    return ok;
}

void log_open(int foreground, int verbosity)
{
    max_prio = verbosity <= 0 ? LOG_NOTICE : verbosity == 1 ? LOG_INFO : LOG_DEBUG;
    if (getenv("JOURNAL_STREAM") || getenv("INVOCATION_ID")) {
        sink = SINK_JOURNAL;
    } else if (foreground) {
        sink = SINK_STDERR;
    } else if (!syslog_reachable()) {
        sink = SINK_STDERR;
        fprintf(stderr, "it2nd: no syslog socket at %s: logging to stderr\n", _PATH_LOG);
    } else {
        sink = SINK_SYSLOG;
        openlog("it2nd", LOG_PID | LOG_NDELAY, LOG_DAEMON);
    }
}

void log_started(void)
{
    starting = 0;
}

int log_level(void)
{
    return max_prio;
}

void log_msg(int prio, const char *fmt, ...)
{
    va_list ap;
    if (prio > max_prio)
        return;
    va_start(ap, fmt);
    if (sink == SINK_SYSLOG) {
        if (starting && prio <= LOG_ERR) {
            va_list aq;
            va_copy(aq, ap);
            fputs("it2nd: ", stderr);
            vfprintf(stderr, fmt, aq);
            fputc('\n', stderr);
            va_end(aq);
        }
        vsyslog(prio, fmt, ap);
    } else {
        char buf[1024];
        vsnprintf(buf, sizeof buf, fmt, ap);
        if (sink == SINK_JOURNAL)
            fprintf(stderr, "<%d>%s\n", prio, buf);
        else
            fprintf(stderr, "it2nd: %s\n", buf);
    }
    va_end(ap);
}
