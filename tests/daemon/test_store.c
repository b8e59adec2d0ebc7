/* test_store — WAL and snapshot: replay after "crash" (no snapshot),
 * group commit, truncated and corrupted records dropped with everything
 * before them kept, snapshot + WAL, records already in a snapshot skipped,
 * corrupted snapshot ignored. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmocka.h>

#include "models.h"
#include "store.h"

static char dir[64];

static struct model *fresh(void)
{
    models_free();
    assert_int_equal(models_init(4), 0);
    struct model *md = models_add(1, 1, 1, 1, IT2N_F_TYPE1);
    assert_non_null(md);
    models_set_journal(store_append, NULL);
    return md;
}

static void put(struct model *md, unsigned i, unsigned j, int x, int y, int t)
{
    it2n_val v[IT2N_CH_COUNT] = { 0 };
    it2n_errinfo err;
    v[IT2N_CH_X] = (it2n_val)x * IT2N_VAL_ONE;
    v[IT2N_CH_Y] = (it2n_val)y * IT2N_VAL_ONE;
    v[IT2N_CH_T] = (it2n_val)t * IT2N_VAL_ONE / 10;
    assert_int_equal(models_put(md, i, j, IT2N_FP_D, v, true, &err), IT2N_OK);
}

static void path(char *buf, size_t size, const char *name)
{
    snprintf(buf, size, "%s/%s", dir, name);
}

static long fsize(const char *name)
{
    char p[128];
    struct stat st;
    path(p, sizeof p, name);
    return stat(p, &st) ? -1 : (long)st.st_size;
}

static void cut(const char *name, long len)
{
    char p[128];
    path(p, sizeof p, name);
    assert_int_equal(truncate(p, len), 0);
}

static void flip(const char *name, long off)
{
    char p[128];
    path(p, sizeof p, name);
    FILE *f = fopen(p, "r+b");
    fseek(f, off, SEEK_SET);
    int c = fgetc(f);
    fseek(f, off, SEEK_SET);
    fputc(c ^ 0x55, f);
    fclose(f);
}

static int setup(void **st)
{
    (void)st;
    snprintf(dir, sizeof dir, "/tmp/it2nd-test-store.%d", (int)getpid());
    return 0;
}

static int teardown(void **st)
{
    char cmd[128];
    (void)st;
    store_close();
    models_free();
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    return system(cmd) == 0 ? 0 : -1;
}

static void test_wal_replay(void **st)
{
    (void)st;
    struct model *md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    put(md, 0, 0, 0, 0, 1);
    put(md, 0, 1, 0, 10, 2);
    put(md, 1, 0, 10, 0, 3);
    assert_int_equal(store_pending(), 3);
    assert_int_equal(store_commit(), 0); /* group commit: one write */
    assert_int_equal(store_pending(), 0);
    put(md, 1, 1, 10, 10, 4); /* completes: solved */
    assert_int_equal(store_commit(), 0);
    assert_int_equal(md->state, IT2N_RS_SOLVED);
    it2n_model solved = md->mdl;
    store_close(); /* "crash": no snapshot */

    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(md->state, IT2N_RS_SOLVED);
    assert_memory_equal(md->mdl.ctrl, solved.ctrl, sizeof solved.ctrl);
    store_close();

    /* A torn last record: the three before it survive. */
    long len = fsize("wal");
    cut("wal", len - 5);
    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(md->state, IT2N_RS_INCOMPLETE);
    assert_int_equal(models_present(md), 3);
    assert_int_equal(fsize("wal"), len - 5 - (len - 16) / 4 + 5); /* truncated at the last good record */
    store_close();

    /* A corrupted byte in the second record: only the first survives. */
    flip("wal", 16 + (len - 16) / 4 + 20);
    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(models_present(md), 1);
    store_close();
}

static void test_snapshot(void **st)
{
    char a[128], b[128];
    (void)st;
    struct model *md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    models_clear(md);
    put(md, 0, 0, 0, 0, 1);
    put(md, 0, 1, 0, 10, 2);
    put(md, 1, 0, 10, 0, 3);
    put(md, 1, 1, 10, 10, 4);
    assert_int_equal(store_commit(), 0);
    /* Keep the pre-snapshot WAL to simulate a crash between the snapshot
     * rename and the WAL reset. */
    path(a, sizeof a, "wal");
    path(b, sizeof b, "wal.old");
    assert_int_equal(link(a, b), 0);
    assert_int_equal(store_snapshot(), 0);
    assert_int_equal(fsize("wal"), 16);
    put(md, 1, 1, 10, 10, 5); /* update after the snapshot */
    assert_int_equal(store_commit(), 0);
    it2n_model want = md->mdl;
    uint32_t gen = md->gen;
    store_close();

    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(md->state, IT2N_RS_SOLVED);
    assert_int_equal(md->gen, gen);
    assert_memory_equal(md->mdl.ctrl, want.ctrl, sizeof want.ctrl);
    store_close();

    /* Old WAL back in place: its records are all in the snapshot. */
    assert_int_equal(rename(b, a), 0);
    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(md->state, IT2N_RS_SOLVED);
    assert_int_equal(md->gen, gen - 1);  /* snapshot state; the later update was in the replaced WAL */
    store_close();

    /* Corrupted snapshot: ignored; the old WAL still holds every record
     * since the start, so replay rebuilds the model from them. */
    flip("snapshot", fsize("snapshot") / 2);
    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(md->state, IT2N_RS_SOLVED);
    assert_int_equal(models_present(md), 4);
    store_close();

    /* Corrupted snapshot and an empty WAL: the model starts from its
     * configuration (empty), never from unvalidated data. */
    cut("wal", 16);
    md = fresh();
    assert_int_equal(store_open(dir, 0), 0);
    assert_int_equal(md->state, IT2N_RS_EMPTY);
    store_close();
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wal_replay),
        cmocka_unit_test(test_snapshot),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
