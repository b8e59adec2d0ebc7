/* models.c — see models.h. */
#include "models.h"

#include <stdlib.h>
#include <string.h>

#include "errs.h"
#include "log.h"
#include "paper_data.h"

static struct model **table;
/* Batch backups, parallel to table (models.h, "Batches"). backup: the
 * model as it was before the first change of the batch being gathered
 * (the current loop passes; NULL: untouched). inflight: the model as it was
 * before the first change of the batch the writer thread is making durable
 * (NULL: not in it). The oldest of the two is the last durable state, the
 * one readers see (models_view). */
static struct model **backup, **inflight;
static int nmodels, maxmodels;
static uint32_t instances;
static model_journal_fn journal;
static void *journal_arg;
static int replaying;

int models_init(int max)
{
    table = calloc((size_t)max, sizeof *table);
    backup = calloc((size_t)max, sizeof *backup);
    inflight = calloc((size_t)max, sizeof *inflight);
    if (!table || !backup || !inflight) {
        free(table);
        free(backup);
        free(inflight);
        table = backup = inflight = NULL;
        return -1;
    }
    maxmodels = max;
    nmodels = 0;
    return 0;
}

void models_free(void)
{
    for (int k = 0; k < nmodels; k++) {
        free(table[k]);
        free(backup[k]);
        free(inflight[k]);
    }
    free(table);
    free(backup);
    free(inflight);
    table = backup = inflight = NULL;
    nmodels = maxmodels = 0;
}

void models_set_journal(model_journal_fn fn, void *arg)
{
    journal = fn;
    journal_arg = arg;
}

/* A change refused for a daemon reason (errs.h): err says so, without a
 * point, and so does the model's last_error. */
static int refuse(struct model *md, it2n_errinfo *err, int code)
{
    memset(err, 0, sizeof *err);
    err->code = code;
    err->i = err->j = -1;
    err->fp = err->ch = -1;
    md->last_err = *err;
    return code;
}

/* Copy-on-first-write: remember md as it was before the pass changed it.
 * Replay and preload are not part of a pass (nothing to roll back). */
static int touch(struct model *md)
{
    if (replaying)
        return 0;
    for (int k = 0; k < nmodels; k++) {
        if (table[k] != md)
            continue;
        if (!backup[k]) {
            backup[k] = malloc(sizeof *backup[k]);
            if (!backup[k]) {
                log_err("model %d: no memory for the pass backup; change refused", md->id);
                return -1;
            }
            *backup[k] = *md;
        }
        return 0;
    }
    return 0;
}

int models_pass_dirty(void)
{
    for (int k = 0; k < nmodels; k++)
        if (backup[k] || inflight[k])
            return 1;
    return 0;
}

struct model *models_view(struct model *md)
{
    for (int k = 0; k < nmodels; k++) {
        if (table[k] != md)
            continue;
        struct model *v = inflight[k] ? inflight[k] : backup[k];
        if (!v)
            return md;
        /* Counters and the last refusal are live, not transactional. */
        v->requests = md->requests;
        v->exceptions = md->exceptions;
        v->last_err = md->last_err;
        v->unit = md->unit;
        return v;
    }
    return md;
}

void models_batch_submit(void)
{
    for (int k = 0; k < nmodels; k++) {
        /* A model in both: its durable state is the older copy. */
        if (!inflight[k])
            inflight[k] = backup[k];
        else
            free(backup[k]);
        backup[k] = NULL;
    }
}

/* Put md back as old (keeping the request counters), last_error: I/O. */
static void put_back(struct model *md, const struct model *old)
{
    uint32_t req = md->requests, exc = md->exceptions;
    log_warn("model %d: change not durable; back to generation %u", md->id, old->gen);
    *md = *old;
    md->requests = req;
    md->exceptions = exc;
    /* A new instance: results cached for the undone change (keyed on
     * instance and generation, mb_map) must not be served for a later
     * change that reaches the same generation number. */
    md->instance = ++instances;
    memset(&md->last_err, 0, sizeof md->last_err);
    md->last_err.code = IT2ND_ERR_IO;
    md->last_err.i = md->last_err.j = -1;
    md->last_err.fp = md->last_err.ch = -1;
}

void models_batch_done(int ok, model_changed_fn fn, void *arg)
{
    for (int k = 0; k < nmodels; k++) {
        struct model *md = table[k], *old = inflight[k];
        if (ok) {
            if (!old)
                continue;
            /* The state after the batch: before the next one's changes. */
            const struct model *now = backup[k] ? backup[k] : md;
            if (fn && (old->gen != now->gen || old->state != now->state))
                fn(arg, now, old->state, old->gen);
        } else {
            /* The gathered batch builds on the failed one: both go. */
            const struct model *to = old ? old : backup[k];
            if (to)
                put_back(md, to);
            free(backup[k]);
            backup[k] = NULL;
        }
        free(old);
        inflight[k] = NULL;
    }
}

void models_pass_end(int ok, model_changed_fn fn, void *arg)
{
    models_batch_submit();
    models_batch_done(ok, fn, arg);
}

/* 0, or the journal's negative error code (IT2ND_ERR_*: the WAL cannot
 * take the record; the change is refused). */
static int jlog(const struct model_rec *rec)
{
    int rc;
    if (replaying || !journal)
        return 0;
    rc = journal(journal_arg, rec);
    return rc < 0 ? rc : rc ? IT2ND_ERR_IO : 0;
}


struct model *models_add(int id, int unit, unsigned n, unsigned m, unsigned flags)
{
    struct model *md;
    it2n_errinfo err;
    if (nmodels == maxmodels || models_by_id(id) || models_by_unit(unit))
        return NULL;
    md = calloc(1, sizeof *md);
    if (!md)
        return NULL;
    md->id = id;
    md->unit = unit;
    md->instance = ++instances;
    if (it2n_dataset_init(&md->ds, n, m, flags, &err) != IT2N_OK) {
        free(md);
        return NULL;
    }
    it2n_model_init(&md->mdl);
    md->state = IT2N_RS_EMPTY;
    table[nmodels++] = md;
    return md;
}

void models_remove(struct model *md)
{
    for (int k = 0; k < nmodels; k++) {
        if (table[k] != md)
            continue;
        free(backup[k]); /* NULL outside a pass */
        free(inflight[k]);
        free(md);
        for (int r = k + 1; r < nmodels; r++) {
            table[r - 1] = table[r];
            backup[r - 1] = backup[r];
            inflight[r - 1] = inflight[r];
        }
        nmodels--;
        table[nmodels] = backup[nmodels] = inflight[nmodels] = NULL;
        return;
    }
}

struct model *models_by_id(int id)
{
    for (int k = 0; k < nmodels; k++)
        if (table[k]->id == id)
            return table[k];
    return NULL;
}

struct model *models_by_unit(int unit)
{
    for (int k = 0; k < nmodels; k++)
        if (table[k]->unit == unit)
            return table[k];
    return NULL;
}

int models_count(void)
{
    return nmodels;
}

struct model *models_at(int k)
{
    return k >= 0 && k < nmodels ? table[k] : NULL;
}

unsigned models_required(const struct model *md)
{
    unsigned fps = (md->ds.flags & IT2N_F_TYPE1) ? 1u : IT2N_FP_COUNT;
    return (md->ds.n + 1u) * (md->ds.m + 1u) * fps;
}

unsigned models_present(const struct model *md)
{
    return models_required(md) - it2n_dataset_missing(&md->ds);
}

static void set_err(struct model *md, const it2n_errinfo *err)
{
    md->last_err = *err;
}

/* Solve md->ds into md->mdl. On failure md->mdl is unchanged. */
static int solve(struct model *md, it2n_errinfo *err)
{
    int rc = it2n_model_solve(&md->mdl, &md->ds, err);
    if (rc != IT2N_OK) {
        set_err(md, err);
        return rc;
    }
    md->state = IT2N_RS_SOLVED;
    md->gen++;
    md->solves++;
    memset(&md->last_err, 0, sizeof md->last_err);
    return IT2N_OK;
}

int models_configure(struct model *md, unsigned n, unsigned m, unsigned flags, it2n_errinfo *err)
{
    it2n_dataset ds;
    struct model_rec rec = { .op = MOP_CONFIG, .id = md->id, .n = n, .m = m, .flags = flags };
    int rc = it2n_dataset_init(&ds, n, m, flags, err);
    if (rc != IT2N_OK)
        return rc;
    if (touch(md))
        return refuse(md, err, IT2ND_ERR_NOMEM);
    if ((rc = jlog(&rec)) != 0)
        return refuse(md, err, rc);
    md->ds = ds;
    it2n_model_init(&md->mdl);
    md->state = IT2N_RS_EMPTY;
    md->grid_valid = 0;
    md->gen++;
    md->last_op = MOP_CONFIG;
    return IT2N_OK;
}

int models_clear(struct model *md)
{
    it2n_errinfo err;
    struct model_rec rec = { .op = MOP_CLEAR, .id = md->id };
    int rc;
    if (touch(md))
        return refuse(md, &err, IT2ND_ERR_NOMEM);
    if ((rc = jlog(&rec)) != 0)
        return refuse(md, &err, rc);
    it2n_dataset_init(&md->ds, md->ds.n, md->ds.m, md->ds.flags, &err);
    it2n_model_init(&md->mdl);
    md->state = IT2N_RS_EMPTY;
    md->grid_valid = 0;
    md->gen++;
    md->last_op = MOP_CLEAR;
    return IT2N_OK;
}

int models_put(struct model *md, unsigned i, unsigned j, unsigned fp,
               const it2n_val vals[IT2N_CH_COUNT], bool replace, it2n_errinfo *err)
{
    struct model_rec rec = { .op = MOP_POINT, .id = md->id, .i = i, .j = j, .fp = fp, .replace = replace };
    int rc;
    memcpy(rec.vals, vals, sizeof rec.vals);

    if (!replace && i <= md->ds.n && j <= md->ds.m && fp < IT2N_FP_COUNT &&
        (md->ds.present[i][j] & (1u << fp))) {
        memset(err, 0, sizeof *err);
        err->code = IT2N_ERR_DUPLICATE;
        err->i = (int16_t)i;
        err->j = (int16_t)j;
        err->fp = (int8_t)fp;
        err->ch = -1;
        return IT2N_ERR_DUPLICATE;
    }
    if (touch(md))
        return refuse(md, err, IT2ND_ERR_NOMEM);
    if (md->state == IT2N_RS_SOLVED) {
        /* Incremental: the core's update changes md->ds and md->mdl
         * together and is atomic on error. Keep a copy of both only to
         * undo a journal failure. */
        struct { it2n_model mdl; it2n_dataset ds; } *save = malloc(sizeof *save);
        int jrc;
        if (!save)
            return refuse(md, err, IT2ND_ERR_NOMEM);
        save->mdl = md->mdl;
        save->ds = md->ds;
        rc = it2n_model_update(&md->mdl, &md->ds, i, j, fp, vals, err);
        if (rc == IT2N_OK && (jrc = jlog(&rec)) != 0) {
            md->mdl = save->mdl;
            md->ds = save->ds;
            free(save);
            return refuse(md, err, jrc);
        }
        free(save);
        if (rc != IT2N_OK) {
            set_err(md, err);
            return rc;
        }
        md->gen++;
        md->points_rx++;
        md->last_op = MOP_POINT;
        return IT2N_OK;
    }

    it2n_dataset *save = malloc(sizeof *save);
    int jrc = 0;
    if (!save)
        return refuse(md, err, IT2ND_ERR_NOMEM);
    *save = md->ds;
    int prev_state = md->state;
    uint32_t prev_gen = md->gen, prev_solves = md->solves;
    rc = it2n_dataset_put(&md->ds, i, j, fp, vals, true, err);
    if (rc == IT2N_OK && it2n_dataset_missing(&md->ds) == 0)
        rc = solve(md, err);  /* completion solves; a failure rejects the point */
    if (rc == IT2N_OK && (jrc = jlog(&rec)) != 0)
        rc = jrc;
    if (rc != IT2N_OK) {
        md->ds = *save;
        if (md->state == IT2N_RS_SOLVED) { /* solve ran, journal failed */
            it2n_model_init(&md->mdl);
            md->state = prev_state;
            md->gen = prev_gen;
            md->solves = prev_solves;
        }
        free(save);
        if (jrc)
            return refuse(md, err, jrc);
        set_err(md, err);
        return rc;
    }
    free(save);
    if (md->state != IT2N_RS_SOLVED)
        md->state = IT2N_RS_INCOMPLETE;
    md->points_rx++;
    md->last_op = MOP_POINT;
    return IT2N_OK;
}

int models_commit(struct model *md, it2n_errinfo *err)
{
    struct model_rec rec = { .op = MOP_COMMIT, .id = md->id };
    it2n_model *save;
    int rc, state = md->state;
    uint32_t gen = md->gen, solves = md->solves;
    memset(err, 0, sizeof *err);
    if (it2n_dataset_missing(&md->ds) != 0) {
        err->code = IT2N_ERR_MISSING;
        return IT2N_ERR_MISSING;
    }
    if (touch(md))
        return refuse(md, err, IT2ND_ERR_NOMEM);
    save = malloc(sizeof *save);
    if (!save)
        return refuse(md, err, IT2ND_ERR_NOMEM);
    *save = md->mdl;
    rc = solve(md, err);
    if (rc == IT2N_OK && (rc = jlog(&rec)) != 0) {
        /* Not journaled: the model is as before (not FAILED: the solve
         * worked, the disk did not). */
        md->mdl = *save;
        md->state = state;
        md->gen = gen;
        md->solves = solves;
        free(save);
        return refuse(md, err, rc);
    }
    if (rc != IT2N_OK && md->state != IT2N_RS_SOLVED)
        md->state = IT2N_RS_FAILED;
    if (rc == IT2N_OK)
        md->last_op = MOP_COMMIT;
    free(save);
    return rc;
}

int models_apply(const struct model_rec *rec, it2n_errinfo *err)
{
    struct model *md = models_by_id(rec->id);
    int rc;
    memset(err, 0, sizeof *err);
    if (!md) {
        err->code = IT2N_ERR_INVAL;
        return IT2N_ERR_INVAL;
    }
    replaying = 1;
    switch (rec->op) {
    case MOP_CONFIG:
        rc = models_configure(md, rec->n, rec->m, rec->flags, err);
        break;
    case MOP_POINT:
        rc = models_put(md, rec->i, rec->j, rec->fp, rec->vals, rec->replace, err);
        break;
    case MOP_COMMIT:
        rc = models_commit(md, err);
        break;
    case MOP_CLEAR:
        rc = models_clear(md);
        break;
    default:
        rc = err->code = IT2N_ERR_INVAL;
        break;
    }
    replaying = 0;
    return rc;
}

int models_preload_paper(struct model *md)
{
    it2n_errinfo err;
    int rc = IT2N_OK;
    replaying = 1; /* configuration, not journaled */
    for (size_t k = 0; k < paper_nrows && rc == IT2N_OK; k++) {
        const struct paper_row *r = &paper_rows[k];
        it2n_val v[IT2N_CH_COUNT] = { 0 };
        static const int ch[5] = { IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F };
        int fp = it2n_fp_from_name(r->fp, strlen(r->fp));
        if (fp < 0) {
            rc = fp;
            break;
        }
        for (int c = 0; c < 5 && rc == IT2N_OK; c++)
            rc = it2n_parse_val(r->val[c], strlen(r->val[c]), &v[ch[c]]);
        if (rc == IT2N_OK)
            rc = models_put(md, r->i, r->j, (unsigned)fp, v, false, &err);
    }
    replaying = 0;
    md->points_rx = 0;
    return rc;
}

struct grid_ctx {
    struct model *md;
    unsigned cols;
};

static int grid_cb(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w, const it2n_point *pt)
{
    struct grid_ctx *g = ctx;
    (void)u;
    (void)w;
    for (int k = 0; k < 3; k++)
        g->md->grid[r * g->cols + c][k] = pt->v[IT2N_FP_D][IT2N_CH_T + k];
    return 0;
}

int models_grid(struct model *md, unsigned rows, unsigned cols)
{
    struct grid_ctx g = { md, cols };
    int rc;
    if (md->state != IT2N_RS_SOLVED)
        return IT2N_ERR_STATE;
    if (md->grid_valid && md->grid_gen == md->gen && md->grid_rows == rows && md->grid_cols == cols)
        return IT2N_OK;
    rc = it2n_sample(&md->mdl, rows, cols, grid_cb, &g, NULL);
    if (rc != IT2N_OK)
        return rc;
    md->grid_gen = md->gen;
    md->grid_rows = rows;
    md->grid_cols = cols;
    md->grid_valid = 1;
    return IT2N_OK;
}
