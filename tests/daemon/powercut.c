/* powercut — LD_PRELOAD shim for the power-loss tests
 * (tests/daemon/powercut_test.py, tests/soak/soak.py): keeps, beside the
 * state directory, the image a power cut would leave of it, so that a test
 * can SIGKILL the daemon and roll the directory back to exactly what
 * fsync, fdatasync and directory fsyncs had made durable.
 *
 * The model (POSIX, no help from a journaling file system):
 *   - a file's content is durable as of its last fsync/fdatasync (the whole
 *     file is copied then: unsynced appends, writes and truncations since
 *     are lost at a cut);
 *   - the state directory's entries are durable as of its last fsync (the
 *     listing is recorded then: creates, renames and unlinks since are
 *     undone at a cut). They are also logged in order, so a cut may keep a
 *     prefix of them (a journal that committed some of them on its own);
 *   - the state directory itself exists durably once its parent has been
 *     fsynced after its creation (or if it existed when the shim started).
 * Files are named by an id the shim gives each inode it sees created (an
 * inode number can be reused once the old file is gone). A file is copied
 * right after its sync returns: a write by another thread in between would
 * count as synced too (in it2nd only the writer thread writes the WAL and
 * the checkpoint files, and only between its own syncs). Writes are not
 * intercepted: what was written but not synced is whatever the live file
 * holds beyond the copy, which the harness may keep part of (a torn write).
 *
 *   IT2N_PC_STATE      the state directory (as in the daemon's config)
 *   IT2N_PC_SHADOW     an existing directory for the image; emptied and
 *                      filled at start from the state directory (whatever
 *                      is there at start counts as durable)
 *   IT2N_PC_MODE       "" record what is synced; negative controls:
 *                      "nosync"       fsync/fdatasync return 0, sync and
 *                                     record nothing (acknowledged without
 *                                     durability)
 *                      "nodirsync"    directory fsyncs return 0 and record
 *                                     nothing (a store without them)
 *                      "noparentsync" the same for the parent's fsync only
 *                                     (state_dir's mkdir never made durable)
 *   IT2N_PC_KILL       an event at which the process SIGKILLs itself (a cut
 *                      at a chosen moment): "pre-fsync:snapshot.tmp",
 *                      "post-renameat:wal", "pre-fsync:." (the state
 *                      directory), "post-openat:wal.cut*" (prefix), "#N"
 *                      (the Nth event of any kind)
 *   IT2N_PC_KILL_SKIP  matching events let through first (default 0)
 *   IT2N_PC_ARM        if set, IT2N_PC_KILL counts events only while this
 *                      file exists (the test arms it when its load starts)
 *
 * Events: pre-/post-fsync, pre-/post-fdatasync (NAME "." for the state
 * directory, ".." for its parent), post-openat, post-unlinkat,
 * post-renameat (the new name), post-ftruncate, post-mkdir:state — only
 * for the state directory and its files.
 *
 * Shadow directory:
 *   d/ID    durable content of file ID
 *   ns      "offset N" (of oplog) then "ID NAME" per durable entry
 *   oplog   namespace changes, in order: "C ID NAME", "R OLD NEW", "U NAME"
 *   dir     "1" when the state directory's existence is durable
 *   events  every event, one per line; killed: the event of a self-kill
 * Every file is replaced atomically (tmp + rename), so the image is whole
 * whenever the process dies. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

typedef int (*fd_fn)(int);
typedef int (*trunc_fn)(int, off_t);
typedef int (*openat_fn)(int, const char *, int, ...);
typedef int (*open_fn)(const char *, int, ...);
typedef int (*renameat_fn)(int, const char *, int, const char *);
typedef int (*unlinkat_fn)(int, const char *, int);
typedef int (*mkdir_fn)(const char *, mode_t);

enum { MODE_REAL, MODE_NOSYNC, MODE_NODIRSYNC, MODE_NOPARENTSYNC };

static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static __thread int inside;      /* the shim's own calls pass straight through */
static int active, mode;
static char sdir[PATH_MAX], parent[PATH_MAX], shadow[PATH_MAX];
static const char *kill_spec, *arm;
static long kill_skip, events_armed, kill_matches;
static long oplog_size;
static unsigned next_id = 1;
#define TAB_MAX 8192
static struct { dev_t dev; ino_t ino; unsigned id; } tab[TAB_MAX];
static int ntab;

static fd_fn real_fsync, real_fdatasync;
static trunc_fn real_ftruncate;
static openat_fn real_openat;
static open_fn real_open;
static renameat_fn real_renameat;
static unlinkat_fn real_unlinkat;
static mkdir_fn real_mkdir;

/* dlsym returns an object pointer; copy it into a function pointer. */
#define RESOLVE(var, name) \
    do { void *p_ = dlsym(RTLD_NEXT, name); memcpy(&(var), &p_, sizeof(var)); } while (0)

static void resolve_all(void)
{
    if (real_fsync)
        return;
    RESOLVE(real_fdatasync, "fdatasync");
    RESOLVE(real_ftruncate, "ftruncate");
    RESOLVE(real_openat, "openat");
    RESOLVE(real_open, "open");
    RESOLVE(real_renameat, "renameat");
    RESOLVE(real_unlinkat, "unlinkat");
    RESOLVE(real_mkdir, "mkdir");
    RESOLVE(real_fsync, "fsync");
}

static void die(const char *what)
{
    /* The image can no longer be trusted: stop rather than let a test
     * pass on a wrong one. */
    fprintf(stderr, "powercut: %s: %s\n", what, strerror(errno));
    abort();
}

static void spath(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", shadow, name);
}

static int write_all(int fd, const char *p, size_t len)
{
    while (len) {
        ssize_t w = write(fd, p, len);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        p += w;
        len -= (size_t)w;
    }
    return 0;
}

/* Replace shadow/NAME with len bytes, atomically. */
static void put_file(const char *name, const char *buf, size_t len)
{
    char p[PATH_MAX + 64], tmp[PATH_MAX + 80];
    spath(p, sizeof p, name);
    snprintf(tmp, sizeof tmp, "%s.tmp", p);
    int fd = real_open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0 || write_all(fd, buf, len) || close(fd) || rename(tmp, p))
        die(p);
}

static void append(const char *name, const char *line, long *size)
{
    char p[PATH_MAX + 64];
    spath(p, sizeof p, name);
    int fd = real_open(p, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
    size_t len = strlen(line);
    if (fd < 0 || write_all(fd, line, len) || close(fd))
        die(p);
    if (size)
        *size += (long)len;
}

/* Copy the file open as fd (any access mode, unlinked or not) to d/ID. */
static void copy_fd(int fd, unsigned id)
{
    char src[64], name[32];
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap);
    snprintf(src, sizeof src, "/proc/self/fd/%d", fd);
    int in = real_open(src, O_RDONLY | O_CLOEXEC);
    if (in < 0 || !buf)
        die(src);
    for (;;) {
        if (len == cap) {
            char *nb = realloc(buf, cap *= 2);
            if (!nb)
                die("realloc");
            buf = nb;
        }
        ssize_t n = read(in, buf + len, cap - len);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0)
            die(src);
        if (n == 0)
            break;
        len += (size_t)n;
    }
    close(in);
    snprintf(name, sizeof name, "d/%u", id);
    put_file(name, buf, len);
    free(buf);
}

static unsigned id_of(dev_t dev, ino_t ino)
{
    for (int k = 0; k < ntab; k++)
        if (tab[k].dev == dev && tab[k].ino == ino)
            return tab[k].id;
    return 0;
}

/* A new inode (created now): a fresh id, whatever the number held before. */
static unsigned new_id(dev_t dev, ino_t ino)
{
    int k;
    for (k = 0; k < ntab; k++)
        if (tab[k].dev == dev && tab[k].ino == ino)
            break;
    if (k == ntab) {
        if (ntab == TAB_MAX) {
            errno = ENOSPC;
            die("inode table full");
        }
        ntab++;
    }
    tab[k].dev = dev;
    tab[k].ino = ino;
    tab[k].id = next_id++;
    return tab[k].id;
}

/* 1: fd/dfd is the state directory; 2: its parent; 0: neither. */
static int dir_kind(int fd)
{
    struct stat a, b;
    if (fstat(fd, &a) || !S_ISDIR(a.st_mode))
        return 0;
    if (stat(sdir, &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino)
        return 1;
    if (stat(parent, &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino)
        return 2;
    return 0;
}

static int in_state(int dfd, const char *name)
{
    if (strchr(name, '/'))
        return 0; /* the daemon names its files relative to the directory */
    return dfd != AT_FDCWD && dir_kind(dfd) == 1;
}

/* The state directory's listing becomes the durable namespace. */
static void record_ns(void)
{
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    DIR *d = opendir(sdir);
    const struct dirent *e;
    if (!d || !buf)
        die(sdir);
    len = (size_t)snprintf(buf, cap, "offset %ld\n", oplog_size);
    while ((e = readdir(d)) != NULL) {
        struct stat st;
        char line[NAME_MAX + 32];
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..") || fstatat(dirfd(d), e->d_name, &st,
                                                                            AT_SYMLINK_NOFOLLOW) ||
            !S_ISREG(st.st_mode))
            continue;
        unsigned id = id_of(st.st_dev, st.st_ino);
        if (!id)
            id = new_id(st.st_dev, st.st_ino);
        int n = snprintf(line, sizeof line, "%u %s\n", id, e->d_name);
        if (len + (size_t)n + 1 > cap) {
            char *nb = realloc(buf, cap *= 2);
            if (!nb)
                die("realloc");
            buf = nb;
        }
        memcpy(buf + len, line, (size_t)n + 1);
        len += (size_t)n;
    }
    closedir(d);
    put_file("ns", buf, len);
    free(buf);
}

static void record_dir(void)
{
    struct stat st;
    put_file("dir", stat(sdir, &st) == 0 ? "1\n" : "0\n", 2);
}

/* An event; the process dies here if IT2N_PC_KILL names it. */
static void event(const char *when, const char *call, const char *name)
{
    char ev[NAME_MAX + 64];
    snprintf(ev, sizeof ev, "%s-%s:%s", when, call, name);
    pthread_mutex_lock(&mu);
    char line[sizeof ev + 2];
    snprintf(line, sizeof line, "%s\n", ev);
    append("events", line, NULL);
    int hit = 0;
    if (kill_spec && *kill_spec && (!arm || !*arm || access(arm, F_OK) == 0)) {
        events_armed++;
        size_t n = strlen(kill_spec);
        if (kill_spec[0] == '#')
            hit = events_armed == atol(kill_spec + 1);
        else if (kill_spec[n - 1] == '*')
            hit = !strncmp(ev, kill_spec, n - 1);
        else
            hit = !strcmp(ev, kill_spec);
        if (hit && kill_spec[0] != '#' && kill_matches++ < kill_skip)
            hit = 0;
    }
    if (hit) {
        append("killed", line, NULL);
        kill(getpid(), SIGKILL);
    }
    pthread_mutex_unlock(&mu);
}

static void fd_name(int fd, char *out, size_t n)
{
    char link[64], buf[PATH_MAX];
    snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    ssize_t len = readlink(link, buf, sizeof buf - 1);
    buf[len > 0 ? len : 0] = 0;
    char *del = strstr(buf, " (deleted)");
    if (del)
        *del = 0;
    const char *b = strrchr(buf, '/');
    b = b ? b + 1 : buf;
    size_t bl = strlen(b) < n - 1 ? strlen(b) : n - 1;
    memcpy(out, b, bl);
    out[bl] = 0;
}

__attribute__((constructor)) static void init(void)
{
    const char *s = getenv("IT2N_PC_STATE"), *sh = getenv("IT2N_PC_SHADOW"), *m = getenv("IT2N_PC_MODE");
    resolve_all();
    if (!s || !sh || !*s || !*sh)
        return;
    inside = 1;
    snprintf(sdir, sizeof sdir, "%s", s);
    while (strlen(sdir) > 1 && sdir[strlen(sdir) - 1] == '/')
        sdir[strlen(sdir) - 1] = 0;
    snprintf(parent, sizeof parent, "%s", sdir);
    char *slash = strrchr(parent, '/');
    if (!slash)
        snprintf(parent, sizeof parent, ".");
    else if (slash == parent)
        parent[1] = 0;
    else
        *slash = 0;
    snprintf(shadow, sizeof shadow, "%s", sh);
    mode = !m || !*m ? MODE_REAL : !strcmp(m, "nosync") ? MODE_NOSYNC : !strcmp(m, "nodirsync") ? MODE_NODIRSYNC
           : !strcmp(m, "noparentsync") ? MODE_NOPARENTSYNC : -1;
    if (mode < 0) {
        errno = EINVAL;
        die("IT2N_PC_MODE");
    }
    kill_spec = getenv("IT2N_PC_KILL");
    arm = getenv("IT2N_PC_ARM");
    kill_skip = getenv("IT2N_PC_KILL_SKIP") ? atol(getenv("IT2N_PC_KILL_SKIP")) : 0;
    /* A fresh image: whatever is in the state directory now. */
    char p[PATH_MAX + 64];
    static const char *const files[] = { "ns", "oplog", "dir", "events", "killed" };
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++) {
        spath(p, sizeof p, files[k]);
        unlink(p);
    }
    spath(p, sizeof p, "d");
    DIR *d = opendir(p);
    if (d) {
        const struct dirent *e;
        while ((e = readdir(d)) != NULL)
            if (e->d_name[0] != '.')
                unlinkat(dirfd(d), e->d_name, 0);
        closedir(d);
    } else if (real_mkdir(p, 0700)) {
        die(p);
    }
    append("oplog", "", &oplog_size);
    d = opendir(sdir);
    if (d) {
        const struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            struct stat st;
            if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) || !S_ISREG(st.st_mode))
                continue;
            int fd = real_openat(dirfd(d), e->d_name, O_RDONLY | O_CLOEXEC);
            if (fd < 0)
                die(e->d_name);
            copy_fd(fd, new_id(st.st_dev, st.st_ino));
            close(fd);
        }
        closedir(d);
        record_ns();
    } else {
        put_file("ns", "offset 0\n", 9);
    }
    record_dir();
    active = 1;
    inside = 0;
}

static int do_sync(int fd, int data)
{
    fd_fn real = data ? real_fdatasync : real_fsync;
    const char *call = data ? "fdatasync" : "fsync";
    struct stat st;
    char name[NAME_MAX + 1];
    int kind = 0;
    unsigned id = 0;
    if (!active || inside || fstat(fd, &st))
        return real(fd);
    inside = 1;
    if (S_ISDIR(st.st_mode))
        kind = dir_kind(fd);
    else if (S_ISREG(st.st_mode)) {
        pthread_mutex_lock(&mu);
        id = id_of(st.st_dev, st.st_ino);
        pthread_mutex_unlock(&mu);
        kind = id ? 3 : 0;
    }
    if (!kind) {
        inside = 0;
        return real(fd);
    }
    if (kind == 1)
        snprintf(name, sizeof name, ".");
    else if (kind == 2)
        snprintf(name, sizeof name, "..");
    else
        fd_name(fd, name, sizeof name);
    event("pre", call, name);
    int skip = mode == MODE_NOSYNC || (mode == MODE_NODIRSYNC && kind != 3) ||
               (mode == MODE_NOPARENTSYNC && kind == 2);
    int rc = skip ? 0 : real(fd);
    if (rc == 0 && !skip) {
        pthread_mutex_lock(&mu);
        if (kind == 1)
            record_ns();
        else if (kind == 2)
            record_dir();
        else
            copy_fd(fd, id);
        pthread_mutex_unlock(&mu);
    }
    event("post", call, name);
    inside = 0;
    return rc;
}

int fsync(int fd)
{
    resolve_all();
    return do_sync(fd, 0);
}

int fdatasync(int fd)
{
    resolve_all();
    return do_sync(fd, 1);
}

int ftruncate(int fd, off_t len)
{
    resolve_all();
    int rc = real_ftruncate(fd, len), e = errno;
    struct stat st;
    if (active && !inside && fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) {
        pthread_mutex_lock(&mu);
        unsigned id = id_of(st.st_dev, st.st_ino);
        pthread_mutex_unlock(&mu);
        if (id) {
            char name[NAME_MAX + 1];
            inside = 1;
            fd_name(fd, name, sizeof name);
            event("post", "ftruncate", name);
            inside = 0;
        }
    }
    errno = e;
    return rc;
}

int openat(int dfd, const char *name, int flags, ...)
{
    mode_t m = 0;
    resolve_all();
    if (flags & (O_CREAT | O_TMPFILE)) {
        va_list ap;
        va_start(ap, flags);
        m = (mode_t)va_arg(ap, int);
        va_end(ap);
    }
    if (!active || inside || !in_state(dfd, name))
        return real_openat(dfd, name, flags, m);
    inside = 1;
    pthread_mutex_lock(&mu);
    struct stat st;
    int existed = fstatat(dfd, name, &st, AT_SYMLINK_NOFOLLOW) == 0;
    int fd = real_openat(dfd, name, flags, m), e = errno;
    if (fd >= 0 && !existed && (flags & O_CREAT) && fstat(fd, &st) == 0) {
        char line[NAME_MAX + 32];
        snprintf(line, sizeof line, "C %u %s\n", new_id(st.st_dev, st.st_ino), name);
        append("oplog", line, &oplog_size);
    }
    pthread_mutex_unlock(&mu);
    event("post", "openat", name);
    inside = 0;
    errno = e;
    return fd;
}

int renameat(int ofd, const char *oldname, int nfd, const char *newname)
{
    resolve_all();
    if (!active || inside || !in_state(ofd, oldname) || !in_state(nfd, newname))
        return real_renameat(ofd, oldname, nfd, newname);
    inside = 1;
    pthread_mutex_lock(&mu);
    int rc = real_renameat(ofd, oldname, nfd, newname), e = errno;
    if (rc == 0) {
        char line[2 * NAME_MAX + 8];
        snprintf(line, sizeof line, "R %s %s\n", oldname, newname);
        append("oplog", line, &oplog_size);
    }
    pthread_mutex_unlock(&mu);
    event("post", "renameat", newname);
    inside = 0;
    errno = e;
    return rc;
}

int unlinkat(int dfd, const char *name, int flags)
{
    resolve_all();
    if (!active || inside || !in_state(dfd, name))
        return real_unlinkat(dfd, name, flags);
    inside = 1;
    pthread_mutex_lock(&mu);
    int rc = real_unlinkat(dfd, name, flags), e = errno;
    if (rc == 0) {
        char line[NAME_MAX + 8];
        snprintf(line, sizeof line, "U %s\n", name);
        append("oplog", line, &oplog_size);
    }
    pthread_mutex_unlock(&mu);
    event("post", "unlinkat", name);
    inside = 0;
    errno = e;
    return rc;
}

int mkdir(const char *path, mode_t m)
{
    resolve_all();
    int rc = real_mkdir(path, m), e = errno;
    if (active && !inside && rc == 0) {
        char p[PATH_MAX];
        snprintf(p, sizeof p, "%s", path);
        while (strlen(p) > 1 && p[strlen(p) - 1] == '/')
            p[strlen(p) - 1] = 0;
        if (!strcmp(p, sdir)) {
            inside = 1;
            event("post", "mkdir", "state");
            inside = 0;
        }
    }
    errno = e;
    return rc;
}
