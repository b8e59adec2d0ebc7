/* models.c — see models.h. */
#include "models.h"

#include <stdlib.h>
#include <string.h>

#include "errs.h"
#include "log.h"
#include "paper_data.h"

static struct model **table;
/* Per model (parallel to table): the batch bookkeeping and the readers'
 * view (models.h, "Batches"). in_flight / in_gathered: the model has undo
 * records in the batch the writer is making durable / in the batch being
 * gathered; hdr_flight / hdr_gathered: its header at the start of that
 * batch (the old state and generation for the change callback, the header
 * the callback sees). view: md as of the last durable state, built on
 * demand from md and the undo log (view_ok), kept until a batch ends. */
struct slot {
    int in_flight, in_gathered;
    unsigned char hdr_flight[MODEL_HDR_BYTES], hdr_gathered[MODEL_HDR_BYTES];
    struct model *view;
    int view_ok;
    /* rollback_to: the live fields kept across an undo */
    int touched;
    uint32_t req, exc;
    it2n_errinfo le;
};
static struct slot *slots;
static int nmodels, maxmodels;
static uint32_t instances;
static model_journal_fn journal;
static void *journal_arg;
static model_jmark_fn jmark_fn;
static model_jrewind_fn jrewind_fn;
static int replaying;
static struct model *scratch; /* header-only copy for the change callback */

/* The undo log: records {model, offset, length, old bytes}, appended as
 * operations overwrite model bytes, oldest first. Records [0, flight_end)
 * belong to the batch in flight, the rest to the batch being gathered. */
struct undo_rec {
    struct model *md;
    uint32_t off, len;
};
/* Record, old bytes, padding to 8, then the record's size (u64). */
#define UREC_SIZE(len) (((sizeof(struct undo_rec) + (len) + 7u) & ~(size_t)7u) + sizeof(uint64_t))
static unsigned char *ulog;
static size_t ulen, ucap, flight_end;

/* The B-spline storage of a model: records, then coefficients, after
 * the struct in the same allocation. */
#define STORAGE_OFF (((sizeof(struct model) + 7u) & ~(size_t)7u))
static size_t bs_recs(unsigned n, unsigned m)
{
    return IT2N_BSPLINE_DATA_RECS(n, m, 0u);
}
static size_t bs_words(unsigned n, unsigned m)
{
    return IT2N_BSPLINE_MODEL_WORDS(n, m, IT2N_F_Z);
}

size_t models_bytes(int kind, unsigned n, unsigned m)
{
    if (kind != MODEL_BSPLINE)
        return sizeof(struct model);
    return STORAGE_OFF + bs_recs(n, m) * sizeof(it2n_bspline_rec) + bs_words(n, m) * sizeof(int32_t);
}

const char *models_kind_name(int kind)
{
    return kind == MODEL_BSPLINE ? "bspline" : "bezier";
}

/* Point md's B-spline data set and model at md's own storage (after a
 * copy of another model's bytes, e.g. the readers' view). */
static void fix_storage(struct model *md)
{
    if (md->kind != MODEL_BSPLINE)
        return;
    md->bds.rec = (it2n_bspline_rec *)(void *)((unsigned char *)md + STORAGE_OFF);
    md->bds.cap = bs_recs(md->cap_n, md->cap_m);
    md->bmdl.coef = (int32_t *)(void *)((unsigned char *)md + STORAGE_OFF +
                                        bs_recs(md->cap_n, md->cap_m) * sizeof(it2n_bspline_rec));
    md->bmdl.cap = bs_words(md->cap_n, md->cap_m);
}

struct model *models_dup(const struct model *md)
{
    struct model *c = malloc(md->bytes);
    if (c) {
        memcpy(c, md, md->bytes);
        fix_storage(c);
    }
    return c;
}

void models_copy(struct model *dst, const struct model *src)
{
    if (dst->bytes != src->bytes || dst->kind != src->kind)
        return; /* not the same storage: left alone */
    memcpy(dst, src, src->bytes);
    fix_storage(dst);
}

int models_init(int max)
{
    table = calloc((size_t)max, sizeof *table);
    slots = calloc((size_t)max, sizeof *slots);
    scratch = calloc(1, sizeof *scratch);
    if (!table || !slots || !scratch) {
        free(table);
        free(slots);
        free(scratch);
        table = NULL;
        slots = NULL;
        scratch = NULL;
        return -1;
    }
    maxmodels = max;
    nmodels = 0;
    ulen = flight_end = 0;
    return 0;
}

void models_free(void)
{
    for (int k = 0; k < nmodels; k++) {
        free(table[k]);
        free(slots[k].view);
    }
    free(table);
    free(slots);
    free(scratch);
    free(ulog);
    table = NULL;
    slots = NULL;
    scratch = NULL;
    ulog = NULL;
    ulen = ucap = flight_end = 0;
    nmodels = maxmodels = 0;
}

void models_set_journal(model_journal_fn fn, void *arg)
{
    journal = fn;
    journal_arg = arg;
}

void models_set_journal_marks(model_jmark_fn mark, model_jrewind_fn rewind)
{
    jmark_fn = mark;
    jrewind_fn = rewind;
}

size_t models_undo_bytes(void)
{
    return ulen;
}

static struct slot *slot_of(const struct model *md)
{
    for (int k = 0; k < nmodels; k++)
        if (table[k] == md)
            return &slots[k];
    return NULL;
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

/* Record the len bytes at p (inside *md) before they are overwritten.
 * The first record of a model in the gathered batch also notes its
 * header then. Replay and preload record too (a failed operation undoes
 * itself), and drop their records when done. 0, or -1: no memory. */
static int save(struct model *md, const void *p, size_t len)
{
    size_t need = UREC_SIZE(len);
    if (ulen + need > ucap) {
        size_t cap = ucap ? ucap : 16384;
        while (cap < ulen + need)
            cap *= 2;
        unsigned char *n = realloc(ulog, cap);
        if (!n) {
            log_err("model %d: no memory for the undo log; change refused", md->id);
            return -1;
        }
        ulog = n;
        ucap = cap;
    }
    struct slot *s = replaying ? NULL : slot_of(md);
    if (s && !s->in_gathered) {
        memcpy(s->hdr_gathered, md, MODEL_HDR_BYTES);
        s->in_gathered = 1;
    }
    struct undo_rec r = {md, (uint32_t)((const unsigned char *)p - (const unsigned char *)md), (uint32_t)len};
    uint64_t size = need;
    memcpy(ulog + ulen, &r, sizeof r);
    memcpy(ulog + ulen + sizeof r, p, len);
    memcpy(ulog + ulen + need - sizeof size, &size, sizeof size);
    ulen += need;
    return 0;
}

/* Apply the undo records [from, ulen) in reverse (each record ends with
 * its own size, so the log is walked backwards), onto their models
 * (target NULL; the records are then forgotten) or, for model `only`'s
 * records only, onto target. */
static void undo_range(size_t from, const struct model *only, struct model *target)
{
    size_t pos = ulen;
    while (pos > from) {
        uint64_t size;
        struct undo_rec r;
        memcpy(&size, ulog + pos - sizeof size, sizeof size);
        pos -= (size_t)size;
        memcpy(&r, ulog + pos, sizeof r);
        if (!only || r.md == only)
            memcpy((unsigned char *)(target ? target : r.md) + r.off, ulog + pos + sizeof r, r.len);
    }
    if (!target)
        ulen = from;
}

/* Does model md have undo records at or after pos? */
static int touched_since(const struct model *md, size_t pos)
{
    while (pos < ulen) {
        struct undo_rec r;
        memcpy(&r, ulog + pos, sizeof r);
        if (r.md == md)
            return 1;
        pos += UREC_SIZE(r.len);
    }
    return 0;
}

/* Undo [from, ulen) on the models, keeping their live fields (counters,
 * last_error); each model put back gets a new instance. Models left with
 * no record in the gathered batch are no longer marked as in it. */
static void rollback_to(size_t from, int new_instance)
{
    for (int k = 0; k < nmodels; k++) {
        struct slot *s = &slots[k];
        s->touched = touched_since(table[k], from);
        s->req = table[k]->mb.requests;
        s->exc = table[k]->mb.exceptions;
        s->le = table[k]->last_err;
    }
    undo_range(from, NULL, NULL);
    if (flight_end > ulen)
        flight_end = ulen;
    for (int k = 0; k < nmodels; k++) {
        struct slot *s = &slots[k];
        struct model *md = table[k];
        if (!s->touched)
            continue;
        md->mb.requests = s->req;
        md->mb.exceptions = s->exc;
        md->last_err = s->le;
        /* A new instance: results cached for the undone change (keyed on
         * instance and generation, mb_map) must not be served for a later
         * change that reaches the same generation number. (An operation
         * undoing itself, op_undo, restores the instance too: nothing
         * could see its change.) */
        if (new_instance)
            md->instance = ++instances;
        s->view_ok = 0;
        if (s->in_gathered && !touched_since(md, flight_end))
            s->in_gathered = 0;
    }
}

void models_txn_begin(struct model_txn *t)
{
    t->undo = ulen;
    t->active = 1;
    if (jmark_fn)
        t->jmark = jmark_fn();
    else
        memset(&t->jmark, 0, sizeof t->jmark);
}

void models_txn_commit(struct model_txn *t)
{
    t->active = 0;
}

void models_txn_rollback(struct model_txn *t)
{
    if (!t->active)
        return;
    t->active = 0;
    if (t->undo < ulen)
        rollback_to(t->undo, 1);
    if (jrewind_fn)
        jrewind_fn(t->jmark);
}

int models_pass_dirty(void)
{
    for (int k = 0; k < nmodels; k++)
        if (slots[k].in_flight || slots[k].in_gathered)
            return 1;
    return 0;
}

struct model *models_view(struct model *md)
{
    struct slot *s = slot_of(md);
    if (!s || (!s->in_flight && !s->in_gathered))
        return md;
    struct model *v = s->view;
    if (!s->view_ok) {
        /* md, then every record of it undone, newest first: md as it was
         * before the oldest batch not yet durable. */
        memcpy(v, md, md->bytes);
        undo_range(0, md, v);
        fix_storage(v); /* the copied pointers point into md */
        s->view_ok = 1;
    }
    /* Counters and the last refusal are live, not transactional. */
    v->mb.requests = md->mb.requests;
    v->mb.exceptions = md->mb.exceptions;
    v->last_err = md->last_err;
    v->unit = md->unit;
    return v;
}

void models_batch_submit(void)
{
    /* A model in both batches: its durable state is the older header. */
    for (int k = 0; k < nmodels; k++) {
        struct slot *s = &slots[k];
        if (s->in_gathered && !s->in_flight)
            memcpy(s->hdr_flight, s->hdr_gathered, MODEL_HDR_BYTES);
        s->in_flight |= s->in_gathered;
        s->in_gathered = 0;
    }
    flight_end = ulen;
}

void models_batch_done(int ok, model_changed_fn fn, void *arg)
{
    if (!ok) {
        /* The gathered batch builds on the failed one: both go. */
        for (int k = 0; k < nmodels; k++) {
            struct slot *s = &slots[k];
            if (!s->in_flight && !s->in_gathered)
                continue;
            uint32_t old_gen;
            memcpy(&old_gen, (s->in_flight ? s->hdr_flight : s->hdr_gathered) + offsetof(struct model, gen),
                   sizeof old_gen);
            log_warn("model %d: change not durable; back to generation %u", table[k]->id, old_gen);
        }
        rollback_to(0, 1);
        for (int k = 0; k < nmodels; k++) {
            struct slot *s = &slots[k];
            if (s->in_flight || s->in_gathered) {
                struct model *md = table[k];
                memset(&md->last_err, 0, sizeof md->last_err);
                md->last_err.code = IT2ND_ERR_IO;
                md->last_err.i = md->last_err.j = -1;
                md->last_err.fp = md->last_err.ch = -1;
            }
            s->in_flight = s->in_gathered = 0;
            s->view_ok = 0;
        }
        ulen = flight_end = 0;
        return;
    }
    for (int k = 0; k < nmodels; k++) {
        struct slot *s = &slots[k];
        if (!s->in_flight)
            continue;
        int old_state;
        uint32_t old_gen;
        memcpy(&old_state, s->hdr_flight + offsetof(struct model, state), sizeof old_state);
        memcpy(&old_gen, s->hdr_flight + offsetof(struct model, gen), sizeof old_gen);
        /* The state after the batch: before the next one's changes. */
        const struct model *now = table[k];
        if (s->in_gathered) {
            memcpy(scratch, s->hdr_gathered, MODEL_HDR_BYTES);
            now = scratch;
        }
        s->in_flight = 0;
        s->view_ok = 0;
        if (fn && (old_gen != now->gen || old_state != now->state))
            fn(arg, now, old_state, old_gen);
    }
    /* The in-flight records are no longer needed: the gathered ones move
     * to the front. */
    memmove(ulog, ulog + flight_end, ulen - flight_end);
    ulen -= flight_end;
    flight_end = 0;
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

struct model *models_add(int id, int unit, int kind, unsigned n, unsigned m, unsigned flags)
{
    struct model *md, *view;
    it2n_errinfo err;
    size_t bytes;
    if (nmodels == maxmodels || models_by_id(id) || models_by_unit(unit) ||
        (kind != MODEL_BEZIER && kind != MODEL_BSPLINE) || n < 1 || m < 1 || n > IT2N_BSPLINE_MAX_N ||
        m > IT2N_BSPLINE_MAX_N)
        return NULL;
    bytes = models_bytes(kind, n, m);
    md = calloc(1, bytes);
    view = malloc(bytes); /* the readers' view buffer: models_view cannot fail */
    if (!md || !view) {
        free(md);
        free(view);
        return NULL;
    }
    md->id = id;
    md->unit = unit;
    md->kind = kind;
    md->bytes = bytes;
    md->instance = ++instances;
    if (kind == MODEL_BSPLINE) {
        md->cap_n = n;
        md->cap_m = m;
        fix_storage(md);
        if (it2n_bspline_data_init(&md->bds, md->bds.rec, md->bds.cap, n, m, flags, &err) != IT2N_OK) {
            free(md);
            free(view);
            return NULL;
        }
        it2n_bspline_model_init(&md->bmdl, md->bmdl.coef, md->bmdl.cap);
    } else if (it2n_dataset_init(&md->ds, n, m, flags, &err) != IT2N_OK) {
        free(md);
        free(view);
        return NULL;
    }
    it2n_model_init(&md->mdl);
    md->state = IT2N_REGMAP_STATE_EMPTY;
    memset(&slots[nmodels], 0, sizeof slots[nmodels]);
    slots[nmodels].view = view;
    table[nmodels++] = md;
    return md;
}

void models_remove(struct model *md)
{
    for (int k = 0; k < nmodels; k++) {
        if (table[k] != md)
            continue;
        free(slots[k].view);
        free(md);
        for (int r = k + 1; r < nmodels; r++) {
            table[r - 1] = table[r];
            slots[r - 1] = slots[r];
        }
        nmodels--;
        table[nmodels] = NULL;
        memset(&slots[nmodels], 0, sizeof slots[nmodels]);
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
    unsigned fps = (models_flags(md) & IT2N_F_TYPE1) ? 1u : IT2N_FP_COUNT;
    return (models_n(md) + 1u) * (models_m(md) + 1u) * fps;
}

unsigned models_present(const struct model *md)
{
    return models_required(md) - models_missing(md);
}

unsigned models_n(const struct model *md)
{
    return md->kind == MODEL_BSPLINE ? md->bds.n : md->ds.n;
}

unsigned models_m(const struct model *md)
{
    return md->kind == MODEL_BSPLINE ? md->bds.m : md->ds.m;
}

unsigned models_flags(const struct model *md)
{
    return md->kind == MODEL_BSPLINE ? md->bds.flags : md->ds.flags;
}

unsigned models_missing(const struct model *md)
{
    return md->kind == MODEL_BSPLINE ? (unsigned)it2n_bspline_data_missing(&md->bds) : it2n_dataset_missing(&md->ds);
}

/* Index of footprint fp of (i, j) in the B-spline records (it2n.h's
 * layout), or -1 outside the data set. */
static long bs_index(const struct model *md, unsigned i, unsigned j, unsigned fp)
{
    const it2n_bspline_data *d = &md->bds;
    unsigned nfp = IT2N_BSPLINE_NFP(d->flags);
    if (i > d->n || j > d->m || fp >= IT2N_FP_COUNT || ((d->flags & IT2N_F_TYPE1) && fp != IT2N_FP_D))
        return -1;
    return (long)(((size_t)i * (d->m + 1u) + j) * nfp + (nfp == 1u ? 0u : fp));
}

/* Coefficient words the current sizes use. */
static size_t bs_used_words(const struct model *md)
{
    return IT2N_BSPLINE_MODEL_WORDS(md->bds.n, md->bds.m, md->bds.flags);
}

int models_point_present(const struct model *md, unsigned i, unsigned j, unsigned fp)
{
    if (md->kind == MODEL_BSPLINE) {
        long k = bs_index(md, i, j, fp);
        return k >= 0 && md->bds.rec[k].present != 0;
    }
    return i <= md->ds.n && j <= md->ds.m && fp < IT2N_FP_COUNT && (md->ds.present[i][j] & (1u << fp)) != 0;
}

void models_point_get(const struct model *md, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT])
{
    if (md->kind == MODEL_BSPLINE)
        it2n_bspline_data_get(&md->bds, i, j, fp, vals);
    else if (models_point_present(md, i, j, fp))
        it2n_dataset_get(&md->ds, i, j, fp, vals);
    else
        memset(vals, 0, sizeof(it2n_val) * IT2N_CH_COUNT);
}

void models_point_get_fine(const struct model *md, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT])
{
    if (md->kind == MODEL_BSPLINE)
        it2n_bspline_data_get_fine(&md->bds, i, j, fp, vals);
    else if (models_point_present(md, i, j, fp))
        it2n_dataset_get_fine(&md->ds, i, j, fp, vals);
    else
        memset(vals, 0, sizeof(it2n_val) * IT2N_CH_COUNT);
}

int models_has_fp(const struct model *md, unsigned fp)
{
    if (md->kind == MODEL_BSPLINE)
        return fp < IT2N_FP_COUNT && (!(md->bmdl.flags & IT2N_F_TYPE1) || fp == IT2N_FP_D);
    return it2n_model_has_fp(&md->mdl, fp);
}

int models_eval(const struct model *md, it2n_par u, it2n_par w, it2n_point *out, it2n_errinfo *err)
{
    return md->kind == MODEL_BSPLINE ? it2n_bspline_eval(&md->bmdl, u, w, out, err)
                                     : it2n_eval(&md->mdl, u, w, out, err);
}

int models_deriv(const struct model *md, it2n_par u, it2n_par w, it2n_point *du, it2n_point *dw, it2n_errinfo *err)
{
    return md->kind == MODEL_BSPLINE ? it2n_bspline_deriv(&md->bmdl, u, w, du, dw, err)
                                     : it2n_deriv(&md->mdl, u, w, du, dw, err);
}

int models_locate(const struct model *md, it2n_val x, it2n_val y, it2n_locate_result *out, it2n_errinfo *err)
{
    return md->kind == MODEL_BSPLINE ? it2n_bspline_locate(&md->bmdl, x, y, out, err)
                                     : it2n_locate(&md->mdl, x, y, out, err);
}

int models_sample(const struct model *md, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx, it2n_errinfo *err)
{
    return md->kind == MODEL_BSPLINE ? it2n_bspline_sample(&md->bmdl, rows, cols, cb, ctx, err)
                                     : it2n_sample(&md->mdl, rows, cols, cb, ctx, err);
}

unsigned models_net_rows(const struct model *md)
{
    if (md->kind == MODEL_BSPLINE)
        return md->bmdl.solved ? md->bmdl.n + 3u : 0u;
    return md->mdl.solved ? md->mdl.n + 1u : 0u;
}

unsigned models_net_cols(const struct model *md)
{
    if (md->kind == MODEL_BSPLINE)
        return md->bmdl.solved ? md->bmdl.m + 3u : 0u;
    return md->mdl.solved ? md->mdl.m + 1u : 0u;
}

it2n_val models_coef(const struct model *md, unsigned r, unsigned s, unsigned fp, unsigned ch)
{
    if (md->kind == MODEL_BSPLINE)
        return it2n_bspline_coef(&md->bmdl, r, s, fp, ch);
    return it2n_model_ctrl(&md->mdl, r, s, fp, ch);
}

static void set_err(struct model *md, const it2n_errinfo *err)
{
    md->last_err = *err;
}

/* An operation that failed after recording (and maybe changing) undoes
 * itself: md exactly as before it, bit for bit. */
static void op_undo(struct model *md, size_t mark)
{
    struct slot *s = slot_of(md);
    undo_range(mark, NULL, NULL);
    if (flight_end > ulen)
        flight_end = ulen;
    if (s && s->in_gathered && !touched_since(md, flight_end))
        s->in_gathered = 0;
}

/* The bytes of data point (i, j, fp) in md->ds (B-spline: its record;
 * indices already checked). */
static int save_point(struct model *md, unsigned i, unsigned j, unsigned fp)
{
    if (md->kind == MODEL_BSPLINE) {
        long k = bs_index(md, i, j, fp);
        return k < 0 ? 0 : save(md, &md->bds.rec[k], sizeof md->bds.rec[k]);
    }
    return save(md, md->ds.coord_lo[i][j][fp], sizeof md->ds.coord_lo[i][j][fp]) ||
           save(md, md->ds.memb[i][j][fp], sizeof md->ds.memb[i][j][fp]) ||
           save(md, md->ds.coord_hi[i][j][fp], sizeof md->ds.coord_hi[i][j][fp]) ||
           save(md, &md->ds.present[i][j], sizeof md->ds.present[i][j]);
}

/* What it2n_model_update(.., fp, ..) rewrites: the model's header fields
 * and the nets (mantissas and exponents) of footprint fp, or of every
 * footprint when chord-length parameters follow footprint D (it2n.h). */
static int save_update(struct model *md, unsigned fp)
{
    if (md->kind == MODEL_BSPLINE) {
        /* The model's header and the nets of footprint fp (contiguous:
         * it2n.h's layout, per footprint slot nch nets of (n+3)(m+3)). */
        unsigned nch = IT2N_BSPLINE_NCH(md->bmdl.flags);
        unsigned slot = (md->bmdl.flags & IT2N_F_TYPE1) ? 0u : fp;
        size_t size = (size_t)(md->bmdl.n + 3u) * (md->bmdl.m + 3u) * nch;
        return save(md, &md->bmdl, sizeof md->bmdl) || save(md, md->bmdl.coef + slot * size, size * sizeof(int32_t));
    }
    if ((md->ds.flags & IT2N_F_CHORD) && fp == IT2N_FP_D)
        return save(md, &md->mdl, sizeof md->mdl);
    return save(md, &md->mdl, offsetof(it2n_model, frac)) || save(md, md->mdl.frac[fp], sizeof md->mdl.frac[fp]) ||
           save(md, md->mdl.net[fp], sizeof md->mdl.net[fp]);
}

/* What a solve rewrites: the model (B-spline: its header and the
 * coefficients of the current sizes). */
static int save_model(struct model *md)
{
    if (md->kind == MODEL_BSPLINE)
        return save(md, &md->bmdl, sizeof md->bmdl) || save(md, md->bmdl.coef, bs_used_words(md) * sizeof(int32_t));
    return save(md, &md->mdl, sizeof md->mdl);
}

/* Solve md->ds into md->mdl. On failure md->mdl is unchanged. */
static int solve(struct model *md, it2n_errinfo *err)
{
    int rc = md->kind == MODEL_BSPLINE ? it2n_bspline_solve(&md->bmdl, &md->bds, err)
                                       : it2n_model_solve(&md->mdl, &md->ds, err);
    if (rc != IT2N_OK) {
        set_err(md, err);
        return rc;
    }
    md->state = IT2N_REGMAP_STATE_SOLVED;
    md->gen++;
    md->solves++;
    memset(&md->last_err, 0, sizeof md->last_err);
    return IT2N_OK;
}

/* Configure and clear rewrite the whole data set and net (B-spline:
 * the records and coefficients in use, before and after). */
static int save_all(struct model *md)
{
    if (md->kind == MODEL_BSPLINE)
        return save(md, md, MODEL_HDR_BYTES) || save(md, &md->bds, sizeof md->bds) ||
               save(md, &md->bmdl, sizeof md->bmdl) || save(md, md->bds.rec, md->bds.cap * sizeof *md->bds.rec) ||
               save(md, md->bmdl.coef, md->bmdl.cap * sizeof *md->bmdl.coef);
    return save(md, md, MODEL_HDR_BYTES) || save(md, &md->ds, sizeof md->ds) || save(md, &md->mdl, sizeof md->mdl);
}

/* Start md's data set afresh as n x m with flags, empty model: IT2N_OK or
 * the core's refusal (nothing changed). */
static int reset_data(struct model *md, unsigned n, unsigned m, unsigned flags, it2n_errinfo *err)
{
    if (md->kind == MODEL_BSPLINE) {
        it2n_bspline_data d = md->bds;
        int rc = it2n_bspline_data_init(&d, md->bds.rec, md->bds.cap, n, m, flags, err);
        if (rc != IT2N_OK)
            return rc;
        md->bds = d;
        it2n_bspline_model_init(&md->bmdl, md->bmdl.coef, md->bmdl.cap);
        return IT2N_OK;
    }
    it2n_dataset ds;
    int rc = it2n_dataset_init(&ds, n, m, flags, err);
    if (rc != IT2N_OK)
        return rc;
    md->ds = ds;
    it2n_model_init(&md->mdl);
    return IT2N_OK;
}

int models_configure(struct model *md, unsigned n, unsigned m, unsigned flags, it2n_errinfo *err)
{
    struct model_rec rec = {.op = MOP_CONFIG, .id = md->id, .n = n, .m = m, .flags = flags, .kind = (unsigned)md->kind};
    size_t mark = ulen;
    int rc;
    /* Checked first (nothing recorded): the core's limits and, for a
     * B-spline model, the storage the configuration gave it. */
    if (md->kind == MODEL_BSPLINE) {
        it2n_bspline_data d;
        rc = it2n_bspline_data_init(&d, md->bds.rec, 0, n, m, flags, err);
        if (rc == IT2N_ERR_RANGE && (n > md->cap_n || m > md->cap_m)) {
            /* beyond the storage: say which size and the limit */
            memset(err, 0, sizeof *err);
            err->code = rc;
            err->i = err->j = -1;
            err->fp = -1;
            err->ch = -1;
            err->value = n > md->cap_n ? n : m;
            err->lo = 1;
            err->hi = n > md->cap_n ? md->cap_n : md->cap_m;
            return rc;
        }
        if (rc != IT2N_ERR_RANGE)
            return rc == IT2N_OK ? IT2N_ERR_INVAL : rc;
    } else {
        it2n_dataset ds;
        if ((rc = it2n_dataset_init(&ds, n, m, flags, err)) != IT2N_OK)
            return rc;
    }
    if (save_all(md)) {
        op_undo(md, mark);
        return refuse(md, err, IT2ND_ERR_NOMEM);
    }
    if ((rc = jlog(&rec)) != 0) {
        op_undo(md, mark);
        return refuse(md, err, rc);
    }
    rc = reset_data(md, n, m, flags, err);
    if (rc != IT2N_OK) { /* cannot happen: checked above */
        op_undo(md, mark);
        return rc;
    }
    md->state = IT2N_REGMAP_STATE_EMPTY;
    md->gen++;
    md->last_op = MOP_CONFIG;
    return IT2N_OK;
}

int models_clear(struct model *md)
{
    it2n_errinfo err;
    struct model_rec rec = {.op = MOP_CLEAR, .id = md->id};
    size_t mark = ulen;
    int rc;
    if (save_all(md)) {
        op_undo(md, mark);
        return refuse(md, &err, IT2ND_ERR_NOMEM);
    }
    if ((rc = jlog(&rec)) != 0) {
        op_undo(md, mark);
        return refuse(md, &err, rc);
    }
    reset_data(md, models_n(md), models_m(md), models_flags(md), &err);
    md->state = IT2N_REGMAP_STATE_EMPTY;
    md->gen++;
    md->last_op = MOP_CLEAR;
    return IT2N_OK;
}

/* The core's put (replace) and incremental update for md's kind; fine:
 * vals in the fine layout (T, I, F in Q30). */
static int core_put(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                    bool fine, it2n_errinfo *err)
{
    if (fine)
        return md->kind == MODEL_BSPLINE ? it2n_bspline_data_put_fine(&md->bds, i, j, fp, vals, true, err)
                                         : it2n_dataset_put_fine(&md->ds, i, j, fp, vals, true, err);
    return md->kind == MODEL_BSPLINE ? it2n_bspline_data_put(&md->bds, i, j, fp, vals, true, err)
                                     : it2n_dataset_put(&md->ds, i, j, fp, vals, true, err);
}

static int core_update(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                       bool fine, it2n_errinfo *err)
{
    if (fine)
        return md->kind == MODEL_BSPLINE ? it2n_bspline_update_fine(&md->bmdl, &md->bds, i, j, fp, vals, err)
                                         : it2n_model_update_fine(&md->mdl, &md->ds, i, j, fp, vals, err);
    return md->kind == MODEL_BSPLINE ? it2n_bspline_update(&md->bmdl, &md->bds, i, j, fp, vals, err)
                                     : it2n_model_update(&md->mdl, &md->ds, i, j, fp, vals, err);
}

static int put_point(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                     bool replace, bool fine, it2n_errinfo *err);

int models_put(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT], bool replace,
               it2n_errinfo *err)
{
    return put_point(md, i, j, fp, vals, replace, false, err);
}

int models_put_fine(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                    bool replace, it2n_errinfo *err)
{
    return put_point(md, i, j, fp, vals, replace, true, err);
}

/* A change the core made (rc its result) into the journal: on the core's
 * refusal or a journal failure the undo records since mark restore md and
 * the error is recorded (a journal failure as a refusal). IT2N_OK or it. */
static int journal_or_undo(struct model *md, const struct model_rec *rec, int rc, size_t mark, it2n_errinfo *err)
{
    int jrc = 0;
    if (rc == IT2N_OK && (jrc = jlog(rec)) != 0)
        rc = jrc;
    if (rc != IT2N_OK) {
        op_undo(md, mark);
        if (jrc)
            return refuse(md, err, jrc);
        set_err(md, err);
    }
    return rc;
}

static int put_point(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                     bool replace, bool fine, it2n_errinfo *err)
{
    struct model_rec rec = {.op = MOP_POINT, .id = md->id, .i = i, .j = j, .fp = fp, .replace = replace, .fine = fine};
    size_t mark = ulen;
    int rc;
    memcpy(rec.vals, vals, sizeof rec.vals);

    if (i > models_n(md) || j > models_m(md) || fp >= IT2N_FP_COUNT) {
        /* Refused by the core before anything is looked at. */
        rc = md->state == IT2N_REGMAP_STATE_SOLVED ? core_update(md, i, j, fp, vals, fine, err)
                                                   : core_put(md, i, j, fp, vals, fine, err);
        if (rc == IT2N_OK) { /* cannot happen: the core checks the indices */
            memset(err, 0, sizeof *err);
            err->code = rc = IT2N_ERR_INVAL;
        }
        set_err(md, err);
        return rc;
    }
    if (!replace && models_point_present(md, i, j, fp)) {
        memset(err, 0, sizeof *err);
        err->code = IT2N_ERR_DUPLICATE;
        err->i = (int16_t)i;
        err->j = (int16_t)j;
        err->fp = (int8_t)fp;
        err->ch = -1;
        return IT2N_ERR_DUPLICATE;
    }
    if (save(md, md, MODEL_HDR_BYTES) || save_point(md, i, j, fp) ||
        (md->state == IT2N_REGMAP_STATE_SOLVED && save_update(md, fp))) {
        op_undo(md, mark);
        return refuse(md, err, IT2ND_ERR_NOMEM);
    }
    if (md->state == IT2N_REGMAP_STATE_SOLVED) {
        /* Incremental: the core's update changes md->ds and md->mdl
         * together and is atomic on error; the undo records undo a
         * journal failure. */
        rc = journal_or_undo(md, &rec, core_update(md, i, j, fp, vals, fine, err), mark, err);
        if (rc != IT2N_OK)
            return rc;
        md->gen++;
        md->points_rx++;
        md->last_op = MOP_POINT;
        return IT2N_OK;
    }

    rc = core_put(md, i, j, fp, vals, fine, err);
    if (rc == IT2N_OK && models_missing(md) == 0) {
        /* completion solves; a failure rejects the point */
        if (save_model(md)) {
            op_undo(md, mark);
            return refuse(md, err, IT2ND_ERR_NOMEM);
        }
        rc = solve(md, err);
    }
    rc = journal_or_undo(md, &rec, rc, mark, err);
    if (rc != IT2N_OK)
        return rc;
    if (md->state != IT2N_REGMAP_STATE_SOLVED)
        md->state = IT2N_REGMAP_STATE_INCOMPLETE;
    md->points_rx++;
    md->last_op = MOP_POINT;
    return IT2N_OK;
}

int models_commit(struct model *md, it2n_errinfo *err)
{
    struct model_rec rec = {.op = MOP_COMMIT, .id = md->id};
    size_t mark = ulen;
    int rc;
    memset(err, 0, sizeof *err);
    if (models_missing(md) != 0) {
        err->code = IT2N_ERR_MISSING;
        return IT2N_ERR_MISSING;
    }
    if (save(md, md, MODEL_HDR_BYTES) || save_model(md)) {
        op_undo(md, mark);
        return refuse(md, err, IT2ND_ERR_NOMEM);
    }
    rc = solve(md, err);
    if (rc == IT2N_OK && (rc = jlog(&rec)) != 0) {
        /* Not journaled: the model is as before (not FAILED: the solve
         * worked, the disk did not). */
        op_undo(md, mark);
        return refuse(md, err, rc);
    }
    if (rc != IT2N_OK && md->state != IT2N_REGMAP_STATE_SOLVED)
        md->state = IT2N_REGMAP_STATE_FAILED;
    if (rc == IT2N_OK)
        md->last_op = MOP_COMMIT;
    return rc;
}

int models_set_upload(struct model *md, const uint16_t regs[IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I])
{
    if (save(md, md->mb.upload, sizeof md->mb.upload))
        return IT2ND_ERR_NOMEM;
    memcpy(md->mb.upload, regs, sizeof md->mb.upload);
    return 0;
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
    size_t mark = ulen;
    replaying = 1;
    switch (rec->op) {
    case MOP_CONFIG:
        if (rec->kind != (unsigned)md->kind) { /* the configuration changed the kind since */
            rc = err->code = IT2N_ERR_INVAL;
            break;
        }
        rc = models_configure(md, rec->n, rec->m, rec->flags, err);
        break;
    case MOP_POINT:
        rc = rec->fine ? models_put_fine(md, rec->i, rec->j, rec->fp, rec->vals, rec->replace, err)
                       : models_put(md, rec->i, rec->j, rec->fp, rec->vals, rec->replace, err);
        break;
    case MOP_COMMIT: rc = models_commit(md, err); break;
    case MOP_CLEAR: rc = models_clear(md); break;
    default: rc = err->code = IT2N_ERR_INVAL; break;
    }
    replaying = 0;
    ulen = mark; /* nothing to roll back: drop the records */
    return rc;
}

int models_preload_paper(struct model *md)
{
    it2n_errinfo err;
    int rc = IT2N_OK;
    size_t mark = ulen;
    replaying = 1; /* configuration, not journaled */
    for (size_t k = 0; k < paper_data_nrows && rc == IT2N_OK; k++) {
        const struct paper_row *r = &paper_data_rows[k];
        it2n_val v[IT2N_CH_COUNT] = {0};
        static const int ch[5] = {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F};
        int fp = it2n_fp_from_name(r->fp, strlen(r->fp));
        if (fp < 0) {
            rc = fp;
            break;
        }
        /* memberships at 2^-30 as 'it2n' reads examples/paper_4x4.csv */
        for (int c = 0; c < 5 && rc == IT2N_OK; c++)
            rc = c < 2 ? it2n_parse_val(r->val[c], strlen(r->val[c]), &v[ch[c]])
                       : it2n_parse_memb(r->val[c], strlen(r->val[c]), &v[ch[c]]);
        if (rc == IT2N_OK)
            rc = models_put_fine(md, r->i, r->j, (unsigned)fp, v, false, &err);
    }
    replaying = 0;
    ulen = mark;
    md->points_rx = 0;
    return rc;
}
