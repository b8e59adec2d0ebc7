/* fuzz_tmp.h — a private scratch directory for one fuzzer process,
 * BASE/it2n-fuzzd-PID (BASE: tmpfs /dev/shm when writable, so file I/O
 * costs little; else /tmp). Removed at exit; libFuzzer ends with _Exit(),
 * so each start also removes the directories of processes that are gone. */
#ifndef FUZZ_DAEMON_TMP_H
#define FUZZ_DAEMON_TMP_H

#include <dirent.h>
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define FUZZ_TMP_PREFIX "it2n-fuzzd-"

static char fuzz_tmp_dir[64];

static void fuzz_tmp_remove(const char *path)
{
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", path);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", path);
}

static void fuzz_tmp_cleanup(void)
{
    if (fuzz_tmp_dir[0])
        fuzz_tmp_remove(fuzz_tmp_dir);
}

/* Create the directory once; returns its path. */
static const char *fuzz_tmp(void)
{
    if (!fuzz_tmp_dir[0]) {
        const char *base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
        DIR *d = opendir(base);
        struct dirent *de;
        while (d && (de = readdir(d)) != NULL) {
            char *end;
            size_t pl = strlen(FUZZ_TMP_PREFIX);
            if (strncmp(de->d_name, FUZZ_TMP_PREFIX, pl) != 0)
                continue;
            long pid = strtol(de->d_name + pl, &end, 10);
            if (*end == 0 && pid > 0 && kill((pid_t)pid, 0) != 0 && errno == ESRCH) {
                char stale[300];
                snprintf(stale, sizeof stale, "%s/%s", base, de->d_name);
                fuzz_tmp_remove(stale);
            }
        }
        if (d)
            closedir(d);
        snprintf(fuzz_tmp_dir, sizeof fuzz_tmp_dir, "%s/" FUZZ_TMP_PREFIX "%ld", base, (long)getpid());
        if (mkdir(fuzz_tmp_dir, 0700) != 0 && errno != EEXIST) {
            perror(fuzz_tmp_dir);
            abort();
        }
        atexit(fuzz_tmp_cleanup);
    }
    return fuzz_tmp_dir;
}

/* Write data to path (replacing it). */
static void fuzz_write_file(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f)) {
        perror(path);
        abort();
    }
}

#endif
