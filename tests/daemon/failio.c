/* failio — LD_PRELOAD shim for the durability tests: fails one call site of
 * the durability path on demand, as a dying or full disk would.
 *
 *   IT2N_FAILIO_FLAG   file: calls fail only while it exists
 *   IT2N_FAILIO_CALL   write, fsync, fdatasync, ftruncate, openat, renameat,
 *                      or several separated by commas (write,ftruncate)
 *   IT2N_FAILIO_PATH   suffix of the path the call is about: for fd calls
 *                      the fd's path (/proc/self/fd), for openat the name,
 *                      for renameat the old or the new name ("" = any)
 *   IT2N_FAILIO_SKIP   matching calls let through first (default 0)
 *   IT2N_FAILIO_ERRNO  errno to fail with (default EIO)
 *
 * Every failed call is counted in the file $IT2N_FAILIO_FLAG (one line per
 * failure), so a test can tell that its call site was reached.
 *
 * Slow-disk mode (independent of the above, no flag file needed):
 *   IT2N_FAILIO_DELAY_MS    every fsync and fdatasync first sleeps this long
 *   IT2N_FAILIO_DELAY_CALL  only these calls (default "fsync,fdatasync")
 *
 * Byte-budget mode (a small filesystem where mount is not allowed):
 *   IT2N_FAILIO_BUDGET      file holding a number of bytes: the files of
 *   IT2N_FAILIO_BUDGET_DIR  this directory may occupy that much together
 *                           (each counted as max(allocated, size)); a write
 *                           or fallocate there that would exceed it fails
 *                           with ENOSPC (a write that partly fits is short,
 *                           as on a real filesystem). The file is read at
 *                           every call, so a test can "free space". */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <time.h>
#include <unistd.h>

static int skipped;

typedef ssize_t (*write_fn)(int, const void *, size_t);
typedef int (*fd_fn)(int);
typedef int (*trunc_fn)(int, off_t);
typedef int (*openat_fn)(int, const char *, int, ...);
typedef int (*renameat_fn)(int, const char *, int, const char *);


static int suffix(const char *s, const char *suf)
{
    size_t a = strlen(s), b = strlen(suf);
    return a >= b && !strcmp(s + a - b, suf);
}

static int in_list(const char *list, const char *call)
{
    size_t n = strlen(call);
    for (const char *p = list; (p = strstr(p, call)) != NULL; p += n)
        if ((p == list || p[-1] == ',') && (p[n] == 0 || p[n] == ','))
            return 1;
    return 0;
}

/* Should this call fail? name: the path it is about (NULL: use fd). */
static int fail_now(const char *call, int fd, const char *name, const char *name2)
{
    const char *flag = getenv("IT2N_FAILIO_FLAG"), *want = getenv("IT2N_FAILIO_CALL");
    const char *path = getenv("IT2N_FAILIO_PATH"), *skip = getenv("IT2N_FAILIO_SKIP");
    const char *err = getenv("IT2N_FAILIO_ERRNO");
    char link[64], buf[4096];
    int saved = errno;
    if (!flag || !want || !in_list(want, call) || access(flag, F_OK) != 0) {
        errno = saved;
        return 0;
    }
    if (path && *path) {
        int match = 0;
        if (name)
            match = suffix(name, path) || (name2 && suffix(name2, path));
        else {
            snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
            ssize_t n = readlink(link, buf, sizeof buf - 1);
            if (n > 0) {
                buf[n] = 0;
                match = suffix(buf, path);
            }
        }
        if (!match) {
            errno = saved;
            return 0;
        }
    }
    if (skip && skipped < atoi(skip)) {
        skipped++;
        errno = saved;
        return 0;
    }
    int lfd = open(flag, O_WRONLY | O_APPEND | O_CLOEXEC);
    if (lfd >= 0) {
        int len = snprintf(buf, sizeof buf, "%s\n", call);
        write_fn real_write;
        void *p = dlsym(RTLD_NEXT, "write");
        memcpy(&real_write, &p, sizeof real_write);
        if (real_write && real_write(lfd, buf, (size_t)len) < 0) {
            /* the count is informational */
        }
        close(lfd);
    }
    errno = err ? atoi(err) : EIO;
    return 1;
}

/* Slow-disk mode: sleep before the call (then do it). */
static void delay(const char *call)
{
    const char *ms = getenv("IT2N_FAILIO_DELAY_MS"), *calls = getenv("IT2N_FAILIO_DELAY_CALL");
    int saved = errno;
    if (!ms || atoi(ms) <= 0 || (calls && *calls && !in_list(calls, call))) {
        errno = saved;
        return;
    }
    long n = atol(ms);
    struct timespec ts = { n / 1000, (n % 1000) * 1000000L };
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
    errno = saved;
}

/* Byte-budget mode: how many more bytes the directory may take (-1: the
 * mode is off, or fd is not a file in the directory). *st: fd's stat. */
static long long budget_room(int fd, struct stat *st)
{
    const char *bf = getenv("IT2N_FAILIO_BUDGET"), *dir = getenv("IT2N_FAILIO_BUDGET_DIR");
    char link[64], path[4096], num[32] = "";
    int saved = errno;
    long long room = -1;
    if (!bf || !dir || fd < 0)
        return -1;
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t n = readlink(link, path, sizeof path - 1);
    size_t dl = strlen(dir);
    if (n <= 0 || (size_t)n <= dl || strncmp(path, dir, dl) || path[dl] != '/' || fstat(fd, st) ||
        !S_ISREG(st->st_mode)) {
        errno = saved;
        return -1;
    }
    FILE *f = fopen(bf, "r");
    if (f) {
        if (!fgets(num, sizeof num, f))
            num[0] = 0;
        fclose(f);
    }
    DIR *d = opendir(dir);
    if (d) {
        long long used = 0;
        const struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            struct stat es;
            char p[4200];
            snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
            if (lstat(p, &es) == 0 && S_ISREG(es.st_mode))
                used += (long long)es.st_blocks * 512 > es.st_size ? (long long)es.st_blocks * 512 : es.st_size;
        }
        closedir(d);
        room = atoll(num) - used;
        if (room < 0)
            room = 0;
    }
    errno = saved;
    return room;
}

/* dlsym returns an object pointer; copy it into a function pointer. */
#define REAL(type, name) \
    type real; \
    do { void *p_ = dlsym(RTLD_NEXT, #name); memcpy(&real, &p_, sizeof real); } while (0)

ssize_t write(int fd, const void *buf, size_t len)
{
    REAL(write_fn, write);
    struct stat st;
    long long room;
    if (fd > 2 && fail_now("write", fd, NULL, NULL))
        return -1;
    if (fd > 2 && (room = budget_room(fd, &st)) >= 0) {
        int saved = errno;
        off_t pos = (fcntl(fd, F_GETFL) & O_APPEND) ? st.st_size : lseek(fd, 0, SEEK_CUR);
        long long grow = (long long)pos + (long long)len - (long long)st.st_size;
        errno = saved;
        if (grow > room) {
            if ((long long)len - (grow - room) <= 0) {
                errno = ENOSPC;
                return -1;
            }
            len = (size_t)((long long)len - (grow - room)); /* what fits: a short write */
        }
    }
    return real(fd, buf, len);
}

typedef int (*fallocate_fn)(int, int, off_t, off_t);
int fallocate(int fd, int mode, off_t off, off_t len)
{
    REAL(fallocate_fn, fallocate);
    struct stat st;
    long long room = budget_room(fd, &st);
    if (room >= 0) {
        long long have = (long long)st.st_blocks * 512 > st.st_size ? (long long)st.st_blocks * 512 : st.st_size;
        if ((long long)off + len - have > room) {
            errno = ENOSPC;
            return -1;
        }
    }
    return real(fd, mode, off, len);
}

int fsync(int fd)
{
    REAL(fd_fn, fsync);
    delay("fsync");
    if (fail_now("fsync", fd, NULL, NULL))
        return -1;
    return real(fd);
}

int fdatasync(int fd)
{
    REAL(fd_fn, fdatasync);
    delay("fdatasync");
    if (fail_now("fdatasync", fd, NULL, NULL))
        return -1;
    return real(fd);
}

int ftruncate(int fd, off_t len)
{
    REAL(trunc_fn, ftruncate);
    if (fail_now("ftruncate", fd, NULL, NULL))
        return -1;
    return real(fd, len);
}

int openat(int dfd, const char *name, int flags, ...)
{
    REAL(openat_fn, openat);
    mode_t mode = 0;
    if (flags & (O_CREAT | O_TMPFILE)) {
        va_list ap;
        va_start(ap, flags);
        mode = (mode_t)va_arg(ap, int);
        va_end(ap);
    }
    if (fail_now("openat", -1, name, NULL))
        return -1;
    return real(dfd, name, flags, mode);
}

int renameat(int ofd, const char *oldname, int nfd, const char *newname)
{
    REAL(renameat_fn, renameat);
    if (fail_now("renameat", -1, oldname, newname))
        return -1;
    return real(ofd, oldname, nfd, newname);
}
