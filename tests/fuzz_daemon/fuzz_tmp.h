/* fuzz_tmp.h — a private scratch directory for one fuzzer process (tmpfs
 * /dev/shm when present, so file I/O costs little), removed at exit. */
#ifndef FUZZ_DAEMON_TMP_H
#define FUZZ_DAEMON_TMP_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char fuzz_tmp_dir[64];

static void fuzz_tmp_cleanup(void)
{
    char cmd[128];
    if (fuzz_tmp_dir[0] && strncmp(fuzz_tmp_dir, "/", 1) == 0) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", fuzz_tmp_dir);
        if (system(cmd) != 0)
            fprintf(stderr, "could not remove %s\n", fuzz_tmp_dir);
    }
}

/* Create the directory once; returns its path. */
static const char *fuzz_tmp(void)
{
    if (!fuzz_tmp_dir[0]) {
        snprintf(fuzz_tmp_dir, sizeof fuzz_tmp_dir, "%s/it2n-fuzzd-XXXXXX",
                 access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp");
        if (!mkdtemp(fuzz_tmp_dir)) {
            perror("mkdtemp");
            abort();
        }
        atexit(fuzz_tmp_cleanup);
    }
    return fuzz_tmp_dir;
}

/* Write data to dir/name (replacing it). */
static void fuzz_write_file(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f || (size && fwrite(data, 1, size, f) != size) || fclose(f)) {
        perror(path);
        abort();
    }
}

#endif
