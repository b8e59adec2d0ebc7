/* log — leveled logging: stderr with <N> sd-daemon prefixes under systemd
 * (JOURNAL_STREAM or INVOCATION_ID set) or in the foreground, syslog when
 * detached — or stderr when there is no syslog socket to talk to. */
#ifndef IT2ND_LOG_H
#define IT2ND_LOG_H

#include <syslog.h>

/* Choose the sink. foreground: stderr; under systemd: stderr with <N>
 * prefixes; otherwise syslog with ident "it2nd". verbosity raises the level
 * from LOG_NOTICE (0) to LOG_INFO (1) and LOG_DEBUG (2+). */
void log_open(int foreground, int verbosity);

/* Start-up is over (the daemon is ready): from now on errors go only to
 * the chosen sink. Until then, with syslog as the sink, errors are also
 * printed on stderr, so whoever started the daemon sees why it stopped. */
void log_started(void);

/* Current maximum priority that is printed. */
int log_level(void);

/* printf-style message at a syslog priority. */
void log_msg(int prio, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

#define log_err(...) log_msg(LOG_ERR, __VA_ARGS__)
#define log_warn(...) log_msg(LOG_WARNING, __VA_ARGS__)
#define log_notice(...) log_msg(LOG_NOTICE, __VA_ARGS__)
#define log_info(...) log_msg(LOG_INFO, __VA_ARGS__)
#define log_debug(...) log_msg(LOG_DEBUG, __VA_ARGS__)

#endif
