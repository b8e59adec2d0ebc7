/* log.c — see log.h. */
#include "log.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

enum sink { SINK_STDERR, SINK_JOURNAL, SINK_SYSLOG };

static enum sink sink = SINK_STDERR;
static int max_prio = LOG_NOTICE;

void log_open(int foreground, int verbosity)
{
    max_prio = verbosity <= 0 ? LOG_NOTICE : verbosity == 1 ? LOG_INFO : LOG_DEBUG;
    if (getenv("JOURNAL_STREAM") || getenv("INVOCATION_ID")) {
        sink = SINK_JOURNAL;
    } else if (foreground) {
        sink = SINK_STDERR;
    } else {
        sink = SINK_SYSLOG;
        openlog("it2nd", LOG_PID | LOG_NDELAY, LOG_DAEMON);
    }
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
