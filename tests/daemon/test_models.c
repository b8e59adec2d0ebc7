/* test_models — the model table's transactions (daemon/models.c):
 * begin / commit / rollback over an undo log, each operation undoing
 * itself when the journal (the WAL) refuses its record, batches put back
 * after a failed group commit, the readers' view, and the size of what a
 * write records (never a copy of the whole model).
 *
 * "Bit for bit" below: the whole struct model compared with memcmp against
 * a byte copy taken before, with only the fields that are documented as
 * live (last_error: the report of the refusal; the request/exception
 * counters) copied over first, and, after a transaction or batch rollback,
 * the new instance number (checked to be new). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "errs.h"
#include "models.h"

/* The fake journal: fails the append numbered fail_at (1-based, counted
 * from the last reset; 0 never); records accepted are counted, and the
 * marks give/rewind that count like store_jmark/store_jrewind. */
static int fail_at, appends, queued;

static int journal(void *arg, const struct model_rec *rec)
{
    (void)arg;
    (void)rec;
    appends++;
    if (fail_at && appends == fail_at)
        return IT2ND_ERR_IO;
    queued++;
    return 0;
}

static struct model_jmark jmark(void)
{
    struct model_jmark m = { 0, queued, 0 };
    return m;
}

static void jrewind(struct model_jmark m)
{
    queued = m.recs;
}

static void reset_journal(int at)
{
    fail_at = at;
    appends = 0;
}

static struct model *paper(int id, unsigned flags)
{
    struct model *md = models_add(id, id, MODEL_BEZIER, 3, 3, flags);
    assert_non_null(md);
    assert_int_equal(models_preload_paper(md), IT2N_OK);
    assert_int_equal(md->state, IT2N_REGMAP_STATE_SOLVED);
    return md;
}

static int setup(void **state)
{
    (void)state;
    assert_int_equal(models_init(4), 0);
    models_set_journal(journal, NULL);
    models_set_journal_marks(jmark, jrewind);
    reset_journal(0);
    queued = 0;
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    models_free();
    return 0;
}

/* md equals the byte copy `before` except for the live fields. */
static void assert_same(const struct model *md, const unsigned char *before)
{
    static unsigned char now[sizeof(struct model)];
    memcpy(now, md, sizeof now);
    memcpy(now + offsetof(struct model, last_err), before + offsetof(struct model, last_err), sizeof md->last_err);
    memcpy(now + offsetof(struct model, mb.requests), before + offsetof(struct model, mb.requests),
           sizeof md->mb.requests);
    memcpy(now + offsetof(struct model, mb.exceptions), before + offsetof(struct model, mb.exceptions),
           sizeof md->mb.exceptions);
    for (size_t k = 0; k < sizeof now; k++)
        if (now[k] != before[k])
            fail_msg("model differs at byte %zu of %zu (ds at %zu, mdl at %zu)", k, sizeof now,
                     offsetof(struct model, ds), offsetof(struct model, mdl));
}

static unsigned char *snap(const struct model *md)
{
    unsigned char *b = malloc(sizeof *md);
    assert_non_null(b);
    memcpy(b, md, sizeof *md);
    return b;
}

static void vals_at(const struct model *md, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT],
                    it2n_val dt)
{
    it2n_dataset_get(&md->ds, i, j, fp, v);
    v[IT2N_CH_T] += dt; /* stays inside [0, 1] and the nesting for the paper data */
}

/* Every operation, with the WAL append failing: the model exactly as
 * before, bit for bit (not only the data: header, nets, padding), the
 * undo log empty again, the refusal in last_error, nothing queued. */
static void test_journal_failure_each_operation(void **state)
{
    (void)state;
    struct model *md = paper(1, 0);
    struct model *chord = paper(2, IT2N_F_CHORD);
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    unsigned char *b;

    for (int op = 0; op < 8; op++) {
        struct model *m = op == 6 ? chord : md;
        b = snap(m);
        reset_journal(1);
        int rc = -1;
        switch (op) {
        case 0: /* a point into the solved model: incremental update */
            vals_at(m, 1, 2, IT2N_FP_LL, v, IT2N_VAL_ONE / 100);
            rc = models_put(m, 1, 2, IT2N_FP_LL, v, true, &err);
            break;
        case 1: /* footprint D */
            vals_at(m, 2, 1, IT2N_FP_D, v, -IT2N_VAL_ONE / 100);
            rc = models_put(m, 2, 1, IT2N_FP_D, v, true, &err);
            break;
        case 2:
            rc = models_commit(m, &err);
            break;
        case 3:
            rc = models_configure(m, 2, 4, IT2N_F_Z, &err);
            break;
        case 4:
            rc = models_clear(m);
            break;
        case 5: { /* two points into an incomplete model, the second fails */
            it2n_val z[IT2N_CH_COUNT] = { 0 };
            reset_journal(0);
            assert_int_equal(models_configure(m, 1, 1, IT2N_F_TYPE1, &err), IT2N_OK);
            z[IT2N_CH_T] = IT2N_VAL_ONE / 2;
            assert_int_equal(models_put(m, 0, 0, IT2N_FP_D, z, false, &err), IT2N_OK);
            models_pass_end(1, NULL, NULL);
            free(b);
            b = snap(m);
            queued = 0;
            reset_journal(1);
            z[IT2N_CH_X] = IT2N_VAL_ONE;
            rc = models_put(m, 1, 0, IT2N_FP_D, z, false, &err);
            break;
        }
        case 6: /* chord-length: D moves every net */
            vals_at(m, 1, 1, IT2N_FP_D, v, IT2N_VAL_ONE / 50);
            v[IT2N_CH_X] += IT2N_VAL_ONE / 4;
            rc = models_put(m, 1, 1, IT2N_FP_D, v, true, &err);
            break;
        case 7: { /* the completing point: its solve ran, the WAL refused */
            it2n_val z[IT2N_CH_COUNT] = { 0 };
            reset_journal(0);
            assert_int_equal(models_configure(m, 1, 1, IT2N_F_TYPE1, &err), IT2N_OK);
            for (unsigned k = 0; k < 3; k++) {
                z[IT2N_CH_X] = (it2n_val)(k & 1u) * IT2N_VAL_ONE;
                z[IT2N_CH_Y] = (it2n_val)(k >> 1) * IT2N_VAL_ONE;
                z[IT2N_CH_T] = IT2N_VAL_ONE / 2;
                assert_int_equal(models_put(m, k & 1u, k >> 1, IT2N_FP_D, z, false, &err), IT2N_OK);
            }
            models_pass_end(1, NULL, NULL);
            free(b);
            b = snap(m);
            queued = 0;
            reset_journal(1);
            z[IT2N_CH_X] = z[IT2N_CH_Y] = IT2N_VAL_ONE;
            rc = models_put(m, 1, 1, IT2N_FP_D, z, false, &err);
            break;
        }
        }
        print_message("operation %d: rc %d\n", op, rc);
        assert_int_equal(rc, IT2ND_ERR_IO);
        assert_int_equal(m->last_err.code, IT2ND_ERR_IO);
        assert_same(m, b);
        assert_int_equal(models_undo_bytes(), 0);
        assert_false(models_pass_dirty());
        assert_int_equal(queued, 0);
        free(b);
        models_pass_end(1, NULL, NULL);
    }
}

/* A transaction of several writes where the k-th WAL append fails, for
 * every k: rollback puts the model back bit for bit and rewinds the
 * journal queue to its mark; without a failure, commit keeps all. */
static void test_txn_rollback_at_each_step(void **state)
{
    (void)state;
    struct model *md = paper(1, 0);
    struct model *other = paper(2, 0);
    static const unsigned pts[5][3] = {
        { 0, 0, IT2N_FP_LL }, { 1, 1, IT2N_FP_D }, { 3, 2, IT2N_FP_RL }, { 2, 3, IT2N_FP_R }, { 1, 1, IT2N_FP_D }
    };
    it2n_errinfo err;
    for (int k = 1; k <= 6; k++) {
        unsigned char *b = snap(md), *bo = snap(other);
        uint32_t gen = md->gen;
        struct model_txn t;
        int rc = IT2N_OK, done = 0;
        reset_journal(k <= 5 ? k : 0);
        queued = 3; /* records of earlier requests, not ours to drop */
        models_txn_begin(&t);
        for (int p = 0; p < 5 && rc == IT2N_OK; p++, done++) {
            it2n_val v[IT2N_CH_COUNT];
            vals_at(md, pts[p][0], pts[p][1], pts[p][2], v, (p & 1) ? IT2N_VAL_ONE / 64 : -IT2N_VAL_ONE / 64);
            rc = models_put(md, pts[p][0], pts[p][1], pts[p][2], v, true, &err);
        }
        if (k <= 5) {
            assert_int_equal(rc, IT2ND_ERR_IO);
            assert_int_equal(done, k);
            assert_int_equal(queued, 3 + k - 1);
            uint32_t inst = md->instance, oinst = other->instance;
            models_txn_rollback(&t);
            if (k > 1) /* changes undone: a new instance, caches of them die */
                assert_int_not_equal(md->instance, inst);
            else /* the first write refused itself: nothing to undo */
                assert_int_equal(md->instance, inst);
            assert_int_equal(other->instance, oinst);  /* untouched: unchanged */
            memcpy(b + offsetof(struct model, instance), &md->instance, sizeof md->instance);
            assert_same(md, b);
            assert_same(other, bo);
            assert_int_equal(queued, 3);
            assert_int_equal(models_undo_bytes(), 0);
            assert_false(models_pass_dirty());
        } else {
            assert_int_equal(rc, IT2N_OK);
            models_txn_commit(&t);
            assert_int_equal(md->gen, gen + 5);
            assert_int_equal(queued, 3 + 5);
            assert_true(models_pass_dirty());
            /* Readers still see the state before the transaction. */
            struct model *v = models_view(md);
            assert_ptr_not_equal(v, md);
            assert_int_equal(v->gen, gen);
            assert_memory_equal(&v->ds, b + offsetof(struct model, ds), sizeof v->ds);
            assert_memory_equal(&v->mdl, b + offsetof(struct model, mdl), sizeof v->mdl);
            models_pass_end(1, NULL, NULL);
            assert_ptr_equal(models_view(md), md);
            assert_int_equal(models_undo_bytes(), 0);
        }
        free(b);
        free(bo);
    }
}

/* A failed transaction inside a gathered batch undoes only itself: the
 * earlier changes of the batch stay (and stay undoable). */
static void test_txn_rollback_keeps_batch(void **state)
{
    (void)state;
    struct model *md = paper(1, 0);
    unsigned char *durable = snap(md);
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    vals_at(md, 0, 1, IT2N_FP_D, v, IT2N_VAL_ONE / 32);
    assert_int_equal(models_put(md, 0, 1, IT2N_FP_D, v, true, &err), IT2N_OK);
    unsigned char *mid = snap(md);
    size_t undo = models_undo_bytes();
    struct model_txn t;
    models_txn_begin(&t);
    vals_at(md, 3, 3, IT2N_FP_LR, v, -IT2N_VAL_ONE / 32);
    assert_int_equal(models_put(md, 3, 3, IT2N_FP_LR, v, true, &err), IT2N_OK);
    assert_int_equal(models_configure(md, 2, 2, 0, &err), IT2N_OK);
    models_txn_rollback(&t);
    memcpy(mid + offsetof(struct model, instance), &md->instance, sizeof md->instance);
    assert_same(md, mid);
    assert_int_equal(models_undo_bytes(), undo);
    assert_true(models_pass_dirty());
    /* The batch fails: back to the durable state, new instance, I/O error. */
    uint32_t inst = md->instance;
    models_pass_end(0, NULL, NULL);
    assert_int_equal(md->last_err.code, IT2ND_ERR_IO);
    assert_int_not_equal(md->instance, inst);
    memcpy(durable + offsetof(struct model, instance), &md->instance, sizeof md->instance);
    assert_same(md, durable);
    assert_int_equal(models_undo_bytes(), 0);
    free(durable);
    free(mid);
}

/* Two batches (one in flight, one gathered): the view is the state before
 * the in-flight one; success shows exactly the in-flight batch; failure
 * of the next puts both models back to it. The change callback gets the
 * state right after the in-flight batch. */
static int cb_calls, cb_old_state;
static uint32_t cb_gen, cb_old_gen;
static void changed(void *arg, const struct model *md, int old_state, uint32_t old_gen)
{
    (void)arg;
    cb_calls++;
    cb_gen = md->gen;
    cb_old_state = old_state;
    cb_old_gen = old_gen;
}

static void test_batches(void **state)
{
    (void)state;
    struct model *md = paper(1, 0), *b2 = paper(2, 0);
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    unsigned char *s0 = snap(md), *s0b = snap(b2);
    uint32_t g0 = md->gen;

    vals_at(md, 1, 2, IT2N_FP_RR, v, IT2N_VAL_ONE / 16);
    assert_int_equal(models_put(md, 1, 2, IT2N_FP_RR, v, true, &err), IT2N_OK);
    models_batch_submit();                           /* batch 1 in flight */
    unsigned char *s1 = snap(md);
    vals_at(md, 2, 2, IT2N_FP_D, v, -IT2N_VAL_ONE / 16);
    assert_int_equal(models_put(md, 2, 2, IT2N_FP_D, v, true, &err), IT2N_OK); /* batch 2 gathered */
    vals_at(b2, 0, 0, IT2N_FP_L, v, IT2N_VAL_ONE / 16);
    assert_int_equal(models_put(b2, 0, 0, IT2N_FP_L, v, true, &err), IT2N_OK);
    struct model *view = models_view(md);
    assert_memory_equal(&view->mdl, s0 + offsetof(struct model, mdl), sizeof view->mdl);
    assert_int_equal(view->gen, g0);
    assert_memory_equal(&models_view(b2)->ds, s0b + offsetof(struct model, ds), sizeof md->ds);

    cb_calls = 0;
    models_batch_done(1, changed, NULL);             /* batch 1 durable */
    assert_int_equal(cb_calls, 1);
    assert_int_equal(cb_old_gen, g0);
    assert_int_equal(cb_gen, g0 + 1);
    assert_int_equal(cb_old_state, IT2N_REGMAP_STATE_SOLVED);
    view = models_view(md);
    assert_int_equal(view->gen, g0 + 1);
    assert_memory_equal(&view->ds, s1 + offsetof(struct model, ds), sizeof view->ds);
    assert_memory_equal(&view->mdl, s1 + offsetof(struct model, mdl), sizeof view->mdl);

    models_batch_submit();                           /* batch 2 in flight */
    models_batch_done(0, changed, NULL);             /* and it fails */
    memcpy(s1 + offsetof(struct model, instance), &md->instance, sizeof md->instance);
    memcpy(s0b + offsetof(struct model, instance), &b2->instance, sizeof b2->instance);
    assert_same(md, s1);
    assert_same(b2, s0b);
    assert_int_equal(md->last_err.code, IT2ND_ERR_IO);
    assert_ptr_equal(models_view(md), md);
    assert_int_equal(models_undo_bytes(), 0);
    free(s0);
    free(s0b);
    free(s1);
}

/* What a write records: a point into a solved model records its point,
 * the nets of its footprint and the model's header — a few KiB, not the
 * model (about 30 KiB). A query touches nothing. */
/* ---- The B-spline kind: storage after the struct ----------------------- */

/* Data point (i, j, fp) of a nested B-spline test grid (dt moves T). */
static void bs_vals(unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT], it2n_val dt)
{
    v[IT2N_CH_X] = (it2n_val)i * IT2N_VAL_ONE + (it2n_val)fp * (IT2N_VAL_ONE / 64);
    v[IT2N_CH_Y] = (it2n_val)j * IT2N_VAL_ONE + (it2n_val)fp * (IT2N_VAL_ONE / 64) + (it2n_val)(i * j % 3) * 4096;
    v[IT2N_CH_Z] = (it2n_val)((i * 7 + j * 3) % 5) * IT2N_VAL_ONE + (it2n_val)fp * (IT2N_VAL_ONE / 32);
    v[IT2N_CH_T] = (it2n_val)((i + 2 * j + fp) % 10) * (IT2N_VAL_ONE / 10) + dt;
    v[IT2N_CH_I] = (it2n_val)((3 * i + j) % 7) * (IT2N_VAL_ONE / 8);
    v[IT2N_CH_F] = (it2n_val)((i * j + fp) % 4) * (IT2N_VAL_ONE / 5);
}

/* md's whole allocation equals `before` but for the live fields. */
static void assert_same_bytes(const struct model *md, const unsigned char *before, size_t len)
{
    unsigned char *now = malloc(len);
    assert_non_null(now);
    memcpy(now, md, len);
    memcpy(now + offsetof(struct model, last_err), before + offsetof(struct model, last_err), sizeof md->last_err);
    memcpy(now + offsetof(struct model, mb.requests), before + offsetof(struct model, mb.requests),
           sizeof md->mb.requests + sizeof md->mb.exceptions);
    for (size_t k = 0; k < len; k++)
        if (now[k] != before[k])
            fail_msg("B-spline model differs at byte %zu of %zu", k, len);
    free(now);
}

/* The coefficients of md against a fresh core solve of the same points in
 * storage of its own. */
static void assert_core_solve(const struct model *md)
{
    unsigned n = models_n(md), m = models_m(md), flags = models_flags(md);
    it2n_bspline_rec *rec = calloc(IT2N_BSPLINE_DATA_RECS(n, m, flags), sizeof *rec);
    int32_t *coef = calloc(IT2N_BSPLINE_MODEL_WORDS(n, m, flags), sizeof *coef);
    it2n_bspline_data d;
    it2n_bspline_model bm;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    assert_true(rec && coef);
    assert_int_equal(it2n_bspline_data_init(&d, rec, IT2N_BSPLINE_DATA_RECS(n, m, flags), n, m, flags, &err), 0);
    for (unsigned i = 0; i <= n; i++)
        for (unsigned j = 0; j <= m; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
                if (models_point_present(md, i, j, fp)) {
                    models_point_get(md, i, j, fp, v);
                    assert_int_equal(it2n_bspline_data_put(&d, i, j, fp, v, false, &err), IT2N_OK);
                }
    it2n_bspline_model_init(&bm, coef, IT2N_BSPLINE_MODEL_WORDS(n, m, flags));
    assert_int_equal(it2n_bspline_solve(&bm, &d, &err), IT2N_OK);
    assert_memory_equal(bm.frac, md->bmdl.frac, sizeof bm.frac);
    assert_memory_equal(coef, md->bmdl.coef, IT2N_BSPLINE_MODEL_WORDS(n, m, flags) * sizeof *coef);
    free(rec);
    free(coef);
}

static void test_bspline(void **state)
{
    (void)state;
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    it2n_point p0, p1;
    struct model_txn t;
    struct model *md = models_add(5, 5, MODEL_BSPLINE, 9, 6, IT2N_F_Z);
    memset(&p0, 0, sizeof p0); /* padding compared too */
    memset(&p1, 0, sizeof p1);
    assert_non_null(md);
    assert_int_equal(md->bytes, models_bytes(MODEL_BSPLINE, 9, 6));
    assert_true(md->bytes > sizeof *md + IT2N_BSPLINE_DATA_RECS(9, 6, 0) * sizeof(it2n_bspline_rec));
    assert_int_equal(models_bytes(MODEL_BEZIER, 9, 6), sizeof *md);
    /* beyond the storage the configuration gave it: refused, unchanged */
    unsigned char *b = malloc(md->bytes);
    memcpy(b, md, md->bytes);
    assert_int_equal(models_configure(md, 10, 6, IT2N_F_Z, &err), IT2N_ERR_RANGE);
    assert_int_equal(err.hi, 9);
    assert_int_equal(models_configure(md, 4, 3, IT2N_F_CHORD, &err), IT2N_ERR_INVAL);
    assert_same_bytes(md, b, md->bytes);
    assert_int_equal(models_configure(md, 8, 5, IT2N_F_Z, &err), IT2N_OK);
    models_pass_end(1, NULL, NULL);
    assert_int_equal(models_required(md), 9u * 6u * 7u);
    /* fill; the last point solves */
    for (unsigned i = 0; i <= 8; i++)
        for (unsigned j = 0; j <= 5; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                bs_vals(i, j, fp, v, 0);
                assert_int_equal(models_put(md, i, j, fp, v, false, &err), IT2N_OK);
            }
    assert_int_equal(md->state, IT2N_REGMAP_STATE_SOLVED);
    assert_int_equal(models_net_rows(md), 11);
    assert_int_equal(models_net_cols(md), 8);
    assert_core_solve(md);
    models_pass_end(1, NULL, NULL);
    assert_int_equal(models_eval(md, IT2N_PAR_ONE / 3, IT2N_PAR_ONE / 7, &p0, &err), IT2N_OK);

    /* an update refused by the WAL, and one rolled back: bit for bit */
    for (int way = 0; way < 2; way++) {
        memcpy(b, md, md->bytes);
        uint32_t inst = md->instance;
        bs_vals(4, 2, IT2N_FP_L, v, IT2N_VAL_ONE / 20);
        if (way == 0) {
            reset_journal(1);
            assert_int_equal(models_put(md, 4, 2, IT2N_FP_L, v, true, &err), IT2ND_ERR_IO);
            assert_int_equal(models_undo_bytes(), 0);
        } else {
            reset_journal(0);
            models_txn_begin(&t);
            assert_int_equal(models_put(md, 4, 2, IT2N_FP_L, v, true, &err), IT2N_OK);
            assert_int_equal(models_clear(md), IT2N_OK);
            models_txn_rollback(&t);
            assert_true(md->instance != inst);
            memcpy(b + offsetof(struct model, instance), &md->instance, sizeof md->instance);
        }
        assert_same_bytes(md, b, md->bytes);
        models_pass_end(1, NULL, NULL);
    }
    reset_journal(0);

    /* an update: the core's full solve of the new points; readers see the
     * old state until the batch is durable (their view has storage of its
     * own: its pointers point into the view) */
    bs_vals(4, 2, IT2N_FP_L, v, IT2N_VAL_ONE / 20);
    assert_int_equal(models_put(md, 4, 2, IT2N_FP_L, v, true, &err), IT2N_OK);
    assert_core_solve(md);
    models_batch_submit();
    struct model *view = models_view(md);
    assert_ptr_not_equal(view, md);
    assert_true((unsigned char *)view->bds.rec > (unsigned char *)view &&
                (unsigned char *)view->bmdl.coef < (unsigned char *)view + md->bytes);
    assert_int_equal(models_eval(view, IT2N_PAR_ONE / 3, IT2N_PAR_ONE / 7, &p1, &err), IT2N_OK);
    assert_memory_equal(&p0, &p1, sizeof p0);
    assert_int_equal(models_eval(md, IT2N_PAR_ONE / 3, IT2N_PAR_ONE / 7, &p1, &err), IT2N_OK);
    assert_memory_not_equal(p0.v, p1.v, sizeof p0.v);
    models_batch_done(1, NULL, NULL);
    assert_ptr_equal(models_view(md), md);
    free(b);
}

/* Memory per model in it2nd (docs/daemon.md quotes these lines: the
 * docs-check figure "daemon-memory"): the allocation models_add makes, and
 * as much again for the readers' view buffer. A B-spline model's storage
 * is the core's macros for its configured grid with every footprint and z;
 * checked against them here. */
static void test_memory_figures(void **state)
{
    (void)state;
    static const unsigned side[] = { 4, 16, 64, 128, 256 };
    size_t bez = models_bytes(MODEL_BEZIER, 7, 7);
    assert_int_equal(bez, sizeof(struct model));
    print_message("[memory] %-9s %-19s %10s %16s\n", "kind", "grid", "bytes", "per grid point");
    print_message("[memory] %-9s %-19s %10zu %16s\n", "bezier", "up to 8x8 (any)", bez, "-");
    for (size_t k = 0; k < sizeof side / sizeof side[0]; k++) {
        unsigned n = side[k] - 1;
        size_t b = models_bytes(MODEL_BSPLINE, n, n);
        size_t core = IT2N_BSPLINE_DATA_RECS(n, n, 0) * sizeof(it2n_bspline_rec) +
                      IT2N_BSPLINE_MODEL_WORDS(n, n, IT2N_F_Z) * sizeof(int32_t);
        char grid[32];
        assert_true(b >= sizeof(struct model) + core && b < sizeof(struct model) + core + 8);
        snprintf(grid, sizeof grid, "%ux%u (n=m=%u)", side[k], side[k], n);
        print_message("[memory] %-9s %-19s %10zu %16zu\n", "bspline", grid, b,
                      (b - sizeof(struct model)) / ((size_t)side[k] * side[k]));
    }
}

static void test_undo_size(void **state)
{
    (void)state;
    struct model *md = paper(1, 0);
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    vals_at(md, 2, 1, IT2N_FP_LR, v, IT2N_VAL_ONE / 20);
    assert_int_equal(models_put(md, 2, 1, IT2N_FP_LR, v, true, &err), IT2N_OK);
    size_t one = models_undo_bytes();
    print_message("undo log for one point: %zu bytes; struct model: %zu bytes\n", one, sizeof(struct model));
    assert_true(one > sizeof md->mdl.net[0]);         /* the footprint's nets are in it */
    assert_true(one < sizeof md->mdl.net[0] + 1024u); /* and little else */
    assert_true(one * 8 < sizeof(struct model));
    models_pass_end(1, NULL, NULL);
    assert_int_equal(models_undo_bytes(), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_journal_failure_each_operation, setup, teardown),
        cmocka_unit_test_setup_teardown(test_txn_rollback_at_each_step, setup, teardown),
        cmocka_unit_test_setup_teardown(test_txn_rollback_keeps_batch, setup, teardown),
        cmocka_unit_test_setup_teardown(test_batches, setup, teardown),
        cmocka_unit_test_setup_teardown(test_undo_size, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bspline, setup, teardown),
        cmocka_unit_test(test_memory_figures),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
