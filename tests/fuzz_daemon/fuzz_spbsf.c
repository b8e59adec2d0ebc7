/* Fuzz target "spbsf": arbitrary bytes as state_dir/sparkplug.sf, the
 * Sparkplug store-and-forward file (daemon/spb_sf.c) a power cut or a bad
 * disk may have left. Invariants (abort on violation):
 *  - spb_sf_open returns the number of whole records (>= 0) and cuts the
 *    file to exactly them: every record reads back (spb_sf_read 1) with
 *    at most 65535 metrics, then 0 at the end of the file;
 *  - a record appended then reads back as written (device, time, values);
 *    the bound is kept (full: 1, nothing written);
 *  - a reopen sees the same records; spb_sf_clear leaves none.
 * Built as a libFuzzer target (make fuzzd-fuzz) and, with fuzz_main.c, as a
 * plain corpus run under make test. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "fake_env.h"
#include "fuzz_tmp.h"
#include "spb_sf.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char dir[128], path[200];

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    snprintf(dir, sizeof dir, "%s", fuzz_tmp());
    snprintf(path, sizeof path, "%s/%s", dir, SPB_SF_FILE);
    return 0;
}

static int read_all(void)
{
    uint64_t off = 0;
    struct spb_sf_rec r;
    int n = 0, rc;
    while ((rc = spb_sf_read(&off, &r)) == 1) {
        fuzz_check(r.n >= 1 && r.n <= 65535 && r.idx && r.val, "a record with metrics");
        spb_sf_rec_free(&r);
        n++;
    }
    fuzz_check(rc == 0, "whole records only after open");
    return n;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    int n, max;
    struct spb_payload_val v[2];
    uint16_t idx[2] = { 3, 65535 };
    struct spb_sf_rec r;
    uint64_t off = 0;
    fuzz_write_file(path, data, size);
    max = size ? data[0] % 4 + 1 : 1;
    n = spb_sf_open(dir, 1000000);
    fuzz_check(n >= 0 && n == spb_sf_count(), "open: a count of whole records");
    fuzz_check(read_all() == n, "every kept record reads back");
    spb_sf_close();
    /* Reopened with a small bound: the same records, appends up to it. */
    fuzz_check(spb_sf_open(dir, n + max) == n, "reopen: the same records");
    memset(v, 0, sizeof v);
    v[0].u = 0xFFFFFFFFFFFFFF85ull;  /* -123 */
    v[1].f = -2.5f;
    v[1].null = 1;
    for (int k = 0; k < max; k++)
        fuzz_check(spb_sf_append(7, 1700000000000ull + (uint64_t)k, 2, idx, v) == 0, "append within the bound");
    fuzz_check(spb_sf_append(7, 1, 2, idx, v) == 1 && spb_sf_count() == n + max, "full: refused, nothing written");
    for (int k = 0; k < n; k++) {
        fuzz_check(spb_sf_read(&off, &r) == 1, "old record");
        spb_sf_rec_free(&r);
    }
    fuzz_check(spb_sf_read(&off, &r) == 1 && r.dev == 7 && r.ts == 1700000000000ull && r.n == 2 && r.idx[0] == 3 &&
                   r.idx[1] == 65535 && r.val[0].u == v[0].u && !r.val[0].null && r.val[1].null &&
                   r.val[1].f == -2.5f,
               "the appended record reads back as written");
    spb_sf_rec_free(&r);
    spb_sf_close();
    fuzz_check(spb_sf_open(dir, 10) == n + max && read_all() == n + max, "reopen after appends");
    fuzz_check(spb_sf_clear() == 0 && spb_sf_count() == 0 && read_all() == 0, "clear");
    spb_sf_close();
    return 0;
}
