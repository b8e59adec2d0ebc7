/* failsync — LD_PRELOAD shim for the e2e tests: while the file named by
 * $IT2N_FAILSYNC_FLAG exists, fsync() and fdatasync() fail with EIO, as a
 * dying disk would make them. Lets the tests check what a user sees when
 * the group commit fails (exception 04 / NACK, nothing changed). */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static int failing(void)
{
    const char *flag = getenv("IT2N_FAILSYNC_FLAG");
    return flag && access(flag, F_OK) == 0;
}

typedef int (*sync_fn)(int);

/* dlsym returns an object pointer; copy it into a function pointer. */
static sync_fn next(const char *name)
{
    sync_fn f = NULL;
    void *p = dlsym(RTLD_NEXT, name);
    memcpy(&f, &p, sizeof f);
    return f;
}

int fsync(int fd)
{
    sync_fn real = next("fsync");
    if (failing()) {
        errno = EIO;
        return -1;
    }
    return real ? real(fd) : -1;
}

int fdatasync(int fd)
{
    sync_fn real = next("fdatasync");
    if (failing()) {
        errno = EIO;
        return -1;
    }
    return real ? real(fd) : -1;
}
