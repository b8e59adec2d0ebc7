/* spb_sf.c — see spb_sf.h. */
#include "spb_sf.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "it2n_proto.h"
#include "le_bytes.h"
#include "log.h"

#define HDR 8u         /* len, crc                          */
#define BODY_FIXED 12u /* dev, ts, count                    */
#define VAL 15u        /* idx, null, float bits, integer    */
#define COUNT_MAX 65535u

static struct {
    int fd;
    int max, count;
    uint64_t size;
    char path[4200];
} s = {.fd = -1};

static int full_pread(uint8_t *buf, size_t n, uint64_t off)
{
    size_t got = 0;
    while (got < n) {
        ssize_t r = pread(s.fd, buf + got, n - got, (off_t)(off + got));
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return -1;
        got += (size_t)r;
    }
    return 0;
}

/* The record at off: its total size, or 0 when it is torn or corrupt. */
static uint64_t rec_check(uint64_t off, uint8_t **body)
{
    uint8_t h[HDR];
    uint32_t len;
    uint8_t *b;
    if (off + HDR > s.size || full_pread(h, HDR, off))
        return 0;
    len = le_get32(h);
    if (len < BODY_FIXED || len > BODY_FIXED + COUNT_MAX * VAL || off + HDR + len > s.size || !(b = malloc(len)))
        return 0;
    if (full_pread(b, len, off + HDR) || le_get32(h + 4) != it2n_crc32c(b, len) ||
        BODY_FIXED + le_get16(b + 10) * VAL != len) {
        free(b);
        return 0;
    }
    if (body)
        *body = b;
    else
        free(b);
    return HDR + len;
}

int spb_sf_open(const char *state_dir, int max)
{
    struct stat st;
    uint64_t off = 0, n;
    snprintf(s.path, sizeof s.path, "%s/%s", state_dir, SPB_SF_FILE);
    s.max = max;
    s.count = 0;
    s.fd = open(s.path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (s.fd < 0 || fstat(s.fd, &st)) {
        log_err("sparkplug: %s: %s", s.path, strerror(errno));
        return -1;
    }
    s.size = (uint64_t)st.st_size;
    while ((n = rec_check(off, NULL)) != 0) {
        off += n;
        s.count++;
    }
    if (off != s.size) {
        /* A torn append (the process or the power went mid-write): its
         * change was never acknowledged as stored; the rest is intact. */
        log_warn("sparkplug: %s: %llu bytes after the last whole record (a torn write) cut off; %d record(s) kept",
                 s.path, (unsigned long long)(s.size - off), s.count);
        if (ftruncate(s.fd, (off_t)off) || fdatasync(s.fd)) {
            log_err("sparkplug: %s: %s", s.path, strerror(errno));
            return -1;
        }
        s.size = off;
    }
    return s.count;
}

int spb_sf_count(void)
{
    return s.count;
}

int spb_sf_append(int dev, uint64_t ts, int n, const uint16_t *idx, const struct spb_payload_val *val)
{
    size_t len = BODY_FIXED + (size_t)n * VAL;
    uint8_t *b;
    ssize_t w;
    if (s.fd < 0 || n <= 0 || (unsigned)n > COUNT_MAX)
        return -1;
    if (s.count >= s.max)
        return 1;
    if (!(b = malloc(HDR + len)))
        return -1;
    le_put16(b + HDR, (uint32_t)dev);
    le_put64(b + HDR + 2, ts);
    le_put16(b + HDR + 10, (uint32_t)n);
    for (int k = 0; k < n; k++) {
        uint8_t *p = b + HDR + BODY_FIXED + (size_t)k * VAL;
        uint32_t fb;
        memcpy(&fb, &val[k].f, sizeof fb);
        le_put16(p, idx[k]);
        p[2] = (uint8_t)(val[k].null != 0);
        le_put32(p + 3, fb);
        le_put64(p + 7, val[k].u);
    }
    le_put32(b, (uint32_t)len);
    le_put32(b + 4, it2n_crc32c(b + HDR, len));
    w = pwrite(s.fd, b, HDR + len, (off_t)s.size);
    free(b);
    if (w != (ssize_t)(HDR + len) || fdatasync(s.fd)) {
        log_err("sparkplug: cannot store a change of model-%d in %s: %s", dev, s.path,
                w < 0 || w == (ssize_t)(HDR + len) ? strerror(errno) : "short write");
        /* Nothing half-written stays: the next append starts here again. */
        if (ftruncate(s.fd, (off_t)s.size))
            log_err("sparkplug: %s: %s", s.path, strerror(errno));
        return -1;
    }
    s.size += HDR + len;
    s.count++;
    return 0;
}

int spb_sf_read(uint64_t *off, struct spb_sf_rec *rec)
{
    uint8_t *b = NULL;
    uint64_t n;
    memset(rec, 0, sizeof *rec);
    if (*off >= s.size)
        return 0;
    if (!(n = rec_check(*off, &b)))
        return -1;
    rec->dev = (int)le_get16(b);
    rec->ts = le_get64(b + 2);
    rec->n = (int)le_get16(b + 10);
    rec->idx = calloc((size_t)rec->n, sizeof *rec->idx);
    rec->val = calloc((size_t)rec->n, sizeof *rec->val);
    if (!rec->idx || !rec->val) {
        free(b);
        spb_sf_rec_free(rec);
        return -1;
    }
    for (int k = 0; k < rec->n; k++) {
        const uint8_t *p = b + BODY_FIXED + (size_t)k * VAL;
        uint32_t fb = le_get32(p + 3);
        rec->idx[k] = (uint16_t)le_get16(p);
        rec->val[k].null = p[2] != 0;
        memcpy(&rec->val[k].f, &fb, sizeof fb);
        rec->val[k].u = le_get64(p + 7);
    }
    free(b);
    *off += n;
    return 1;
}

void spb_sf_rec_free(struct spb_sf_rec *rec)
{
    free(rec->idx);
    free(rec->val);
    rec->idx = NULL;
    rec->val = NULL;
}

int spb_sf_clear(void)
{
    if (s.fd < 0)
        return -1;
    if (ftruncate(s.fd, 0) || fdatasync(s.fd)) {
        log_err("sparkplug: cannot empty %s: %s", s.path, strerror(errno));
        return -1;
    }
    s.size = 0;
    s.count = 0;
    return 0;
}

void spb_sf_close(void)
{
    if (s.fd >= 0)
        close(s.fd);
    s.fd = -1;
}
