/*
 * Core test-vector scenarios: the paper's 4x4 model, generated data sets of
 * several degree pairs, type-1, z and chord-length models, incremental
 * update, locate, derivatives, sampling, error reports and text conversion.
 * Every result goes to the output stream (see vec_scenarios.h); big arrays
 * go as a 64-bit FNV-1a hash so the checked-in header stays small.
 */
#include <string.h>

#include "vec_scenarios.h"

typedef struct vec_out {
    it2n_vec_put put;
    void *state;
} vec_out;

static size_t vec_len(const char *s)
{
    size_t n = 0;
    while (s[n] != '\0') {
        n++;
    }
    return n;
}

static void out(const vec_out *o, const char *tag, int64_t v)
{
    o->put(o->state, tag, v);
}

/* ---- Hashing (FNV-1a over little-endian bytes, endian independent) ---- */

#define VEC_FNV_INIT 0xcbf29ce484222325u
#define VEC_FNV_PRIME 0x100000001b3u

static uint64_t hash_i64(uint64_t h, int64_t v)
{
    uint64_t u = (uint64_t)v;
    unsigned k;
    for (k = 0; k < 8u; k++) {
        h ^= (u >> (8u * k)) & 0xffu;
        h *= VEC_FNV_PRIME;
    }
    return h;
}

/* Hash the channels a model really carries (z only with IT2N_F_Z). */
static uint64_t hash_point_v(uint64_t h, const it2n_model *mdl,
                             const it2n_val v[IT2N_FP_COUNT][IT2N_CH_COUNT])
{
    unsigned fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!it2n_model_has_fp(mdl, fp)) {
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (ch == IT2N_CH_Z && !(mdl->flags & IT2N_F_Z)) {
                continue;
            }
            h = hash_i64(h, v[fp][ch]);
        }
    }
    return h;
}

/* The control nets exactly as stored: per footprint and channel the model
 * carries, the exponent, then the (n+1)(m+1) mantissas. */
static uint64_t hash_ctrl(const it2n_model *mdl)
{
    uint64_t h = VEC_FNV_INIT;
    unsigned fp, ch, k, count = (mdl->n + 1u) * (mdl->m + 1u);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!it2n_model_has_fp(mdl, fp)) {
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (ch == IT2N_CH_Z && !(mdl->flags & IT2N_F_Z)) {
                continue;
            }
            h = hash_i64(h, mdl->frac[fp][ch]);
            for (k = 0; k < count; k++) {
                h = hash_i64(h, mdl->net[fp][ch][k]);
            }
        }
    }
    return h;
}

/* The same nets read through it2n_model_ctrl (Q24, rounded). */
static uint64_t hash_ctrl_q24(const it2n_model *mdl)
{
    uint64_t h = VEC_FNV_INIT;
    unsigned i, j, fp, ch;
    for (i = 0; i <= mdl->n; i++) {
        for (j = 0; j <= mdl->m; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!it2n_model_has_fp(mdl, fp)) {
                    continue;
                }
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    if (ch == IT2N_CH_Z && !(mdl->flags & IT2N_F_Z)) {
                        continue;
                    }
                    h = hash_i64(h, it2n_model_ctrl(mdl, i, j, fp, ch));
                }
            }
        }
    }
    return h;
}

/* 1 when two data sets hold the same degrees, flags, entries and values
 * (compared through the core's accessor, not the storage bytes), else 0. */
static int64_t same_data(const it2n_dataset *a, const it2n_dataset *b)
{
    unsigned i, j, fp, ch;
    if (a->n != b->n || a->m != b->m || a->flags != b->flags ||
        memcmp(a->present, b->present, sizeof a->present) != 0) {
        return 0;
    }
    for (i = 0; i < IT2N_DIM; i++) {
        for (j = 0; j < IT2N_DIM; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    if (it2n_dataset_value(a, i, j, fp, ch) !=
                        it2n_dataset_value(b, i, j, fp, ch)) {
                        return 0;
                    }
                }
            }
        }
    }
    return 1;
}

static int64_t as_i64(uint64_t h)
{
    /* Two's complement reinterpretation without implementation-defined
     * conversion. */
    if (h <= (uint64_t)INT64_MAX) {
        return (int64_t)h;
    }
    return -(int64_t)(~h) - 1;
}

/* ---- Recording helpers ---------------------------------------------- */

/* Where an error of eval/deriv/sample/locate was reported (rc < 0). */
static void out_errinfo(const vec_out *o, int rc, const it2n_errinfo *e)
{
    if (rc < 0) {
        out(o, "errinfo.code", e->code);
        out(o, "errinfo.i", e->i);
        out(o, "errinfo.j", e->j);
        out(o, "errinfo.fp", e->fp);
        out(o, "errinfo.ch", e->ch);
        out(o, "errinfo.value", e->value);
    }
}

static void out_err(const vec_out *o, int rc, const it2n_errinfo *e)
{
    out(o, "rc", rc);
    if (rc < 0) {
        out(o, "err.code", e->code);
        out(o, "err.i", e->i);
        out(o, "err.j", e->j);
        out(o, "err.fp", e->fp);
        out(o, "err.ch", e->ch);
    }
}

/* Every channel the model carries, then the summary (seven-footprint
 * models) and the out-of-range mask. */
static void out_point(const vec_out *o, const it2n_model *mdl,
                      const it2n_point *p, bool full)
{
    unsigned fp, ch, k;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!it2n_model_has_fp(mdl, fp)) {
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (ch == IT2N_CH_Z && !(mdl->flags & IT2N_F_Z)) {
                continue;
            }
            out(o, "point.v", p->v[fp][ch]);
        }
    }
    if (!full) {
        return;
    }
    if (!(mdl->flags & IT2N_F_TYPE1)) {
        for (k = 0; k < 3u; k++) {
            out(o, "sum.upper_min", p->sum.upper_min[k]);
            out(o, "sum.upper_max", p->sum.upper_max[k]);
            out(o, "sum.lower_min", p->sum.lower_min[k]);
            out(o, "sum.lower_max", p->sum.lower_max[k]);
        }
    }
    out(o, "point.out_of_range", p->out_of_range);
}

static void eval_at(it2n_vec_work *wk, const vec_out *o, const it2n_model *mdl,
                    it2n_par u, it2n_par w)
{
    int rc;
    memset(&wk->pt, 0, sizeof wk->pt);
    memset(&wk->err, 0, sizeof wk->err);
    rc = it2n_eval(mdl, u, w, &wk->pt, &wk->err);
    out(o, "eval.rc", rc);
    out_errinfo(o, rc, &wk->err);
    if (rc == IT2N_OK) {
        out_point(o, mdl, &wk->pt, true);
    }
}

static void deriv_at(it2n_vec_work *wk, const vec_out *o,
                     const it2n_model *mdl, it2n_par u, it2n_par w)
{
    int rc;
    memset(&wk->du, 0, sizeof wk->du);
    memset(&wk->dw, 0, sizeof wk->dw);
    memset(&wk->err, 0, sizeof wk->err);
    rc = it2n_deriv(mdl, u, w, &wk->du, &wk->dw, &wk->err);
    out(o, "deriv.rc", rc);
    out_errinfo(o, rc, &wk->err);
    if (rc == IT2N_OK) {
        out_point(o, mdl, &wk->du, false);
        out_point(o, mdl, &wk->dw, false);
    }
}

static void locate_at(it2n_vec_work *wk, const vec_out *o,
                      const it2n_model *mdl, it2n_val x, it2n_val y)
{
    unsigned fp, ch;
    int rc;
    memset(&wk->loc, 0, sizeof wk->loc);
    memset(&wk->err, 0, sizeof wk->err);
    rc = it2n_locate(mdl, x, y, &wk->loc, &wk->err);
    out(o, "locate.rc", rc);
    out_errinfo(o, rc, &wk->err);
    if (rc != IT2N_OK) {
        return;
    }
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        const it2n_locate_fp *r = &wk->loc.fp[fp];
        if (!it2n_model_has_fp(mdl, fp)) {
            continue;
        }
        out(o, "locate.status", r->status);
        if (r->status == IT2N_LOC_NOCONV) {
            continue; /* no meaningful position to compare */
        }
        out(o, "locate.u", r->u);
        out(o, "locate.w", r->w);
        out(o, "locate.residual", r->residual);
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            if (ch == IT2N_CH_Z && !(mdl->flags & IT2N_F_Z)) {
                continue;
            }
            out(o, "locate.v", r->v[ch]);
        }
    }
}

/* it2n_sample sink: hash every node; stop with 7 after `stop_after` nodes
 * when non-zero. */
typedef struct sample_state {
    const it2n_model *mdl;
    uint64_t hash;
    uint32_t count, stop_after;
} sample_state;

static int sample_cb(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par w,
                     const it2n_point *pt)
{
    sample_state *s = ctx;
    s->hash = hash_i64(s->hash, (int64_t)r);
    s->hash = hash_i64(s->hash, (int64_t)c);
    s->hash = hash_i64(s->hash, u);
    s->hash = hash_i64(s->hash, w);
    s->hash = hash_point_v(s->hash, s->mdl, pt->v);
    s->hash = hash_i64(s->hash, (int64_t)pt->out_of_range);
    s->count++;
    return (s->stop_after != 0u && s->count >= s->stop_after) ? 7 : 0;
}

static void sample_grid(it2n_vec_work *wk, const vec_out *o,
                        const it2n_model *mdl, unsigned rows, unsigned cols,
                        uint32_t stop_after)
{
    sample_state s;
    int rc;
    s.mdl = mdl;
    s.hash = VEC_FNV_INIT;
    s.count = 0;
    s.stop_after = stop_after;
    memset(&wk->err, 0, sizeof wk->err);
    rc = it2n_sample(mdl, rows, cols, sample_cb, &s, &wk->err);
    out(o, "sample.rc", rc);
    out_errinfo(o, rc, &wk->err);
    out(o, "sample.count", s.count);
    out(o, "sample.hash", as_i64(s.hash));
}

/* Parameter num/den in Q32, rounded to nearest (exact integer maths). */
static it2n_par par(uint32_t num, uint32_t den)
{
    uint64_t q = (((uint64_t)num << 33) / den + 1u) >> 1;
    return (it2n_par)q;
}

#define Q24(units) ((it2n_val)(units) * IT2N_VAL_ONE)

/* ---- Data sets ------------------------------------------------------- */

static int load_paper(it2n_vec_work *wk, const vec_out *o)
{
    unsigned k;
    int rc = it2n_dataset_init(&wk->ds, 3, 3, 0, &wk->err);
    int bad = 0;
    out(o, "paper.init", rc);
    for (k = 0; k < IT2N_VEC_PAPER_ROWS; k++) {
        const it2n_vec_paper_row *r = &it2n_vec_paper[k];
        it2n_val v[IT2N_CH_COUNT];
        v[IT2N_CH_X] = r->x;
        v[IT2N_CH_Y] = r->y;
        v[IT2N_CH_Z] = 0;
        v[IT2N_CH_T] = r->t;
        v[IT2N_CH_I] = r->ind;
        v[IT2N_CH_F] = r->f;
        if (it2n_dataset_put(&wk->ds, r->i, r->j, r->fp, v, false, &wk->err) !=
            IT2N_OK) {
            bad++;
        }
    }
    out(o, "paper.put_failures", bad);
    out(o, "paper.missing", it2n_dataset_missing(&wk->ds));
    return bad;
}

/* Deterministic pseudo-random numbers (LCG, top bits). */
static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8; /* 24 bits */
}

/*
 * A generated grid of degrees n x m: D on a jittered 10-unit lattice, the
 * other footprints offset by 1.5 units per nesting step (so every axis is
 * nested), z a smooth bump, memberships pseudo-random in [0.05, 0.95].
 */
static int make_grid(it2n_dataset *ds, unsigned n, unsigned m, unsigned flags,
                     uint32_t seed, it2n_errinfo *err)
{
    unsigned i, j, fp;
    int rc = it2n_dataset_init(ds, n, m, flags, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= m; j++) {
            it2n_val jx = (it2n_val)(lcg(&seed) >> 2) - ((it2n_val)1 << 21);
            it2n_val jy = (it2n_val)(lcg(&seed) >> 2) - ((it2n_val)1 << 21);
            it2n_val mem[3];
            unsigned k;
            for (k = 0; k < 3u; k++) {
                /* 0.05 + 0.9 * r, r in [0, 1) with 24 bits, then in Q30
                 * with 6 more bits (no further draw: the stream of the
                 * coordinates stays as it was) */
                mem[k] = (IT2N_VAL_ONE / 20) +
                         (((it2n_val)lcg(&seed) * 9) / 10);
                mem[k] = mem[k] * 64 + (it2n_val)((k * 21u + i * 7u + j * 13u) & 63u);
            }
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                it2n_val off = ((it2n_val)fp - IT2N_FP_D) * (3 * IT2N_VAL_ONE / 2);
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                    continue;
                }
                v[IT2N_CH_X] = Q24(10 * (int)i) + jx + off;
                v[IT2N_CH_Y] = Q24(10 * (int)j) + jy + off;
                v[IT2N_CH_Z] = Q24((int)(i * j)) / 4 + off / 3;
                v[IT2N_CH_T] = mem[0];
                v[IT2N_CH_I] = mem[1];
                v[IT2N_CH_F] = mem[2];
                rc = it2n_dataset_put_fine(ds, i, j, fp, v, false, err);
                if (rc != IT2N_OK) {
                    return rc;
                }
            }
        }
    }
    return IT2N_OK;
}

/* ---- Scenarios ------------------------------------------------------- */

static void scen_paper(it2n_vec_work *wk, const vec_out *o)
{
    static const uint32_t at[][4] = {
        {0, 1, 0, 1}, {1, 1, 1, 1}, {1, 2, 1, 2}, {1, 4, 3, 4},
        {1, 1, 0, 1}, {0, 1, 1, 1}, {1, 3, 2, 3}, {7, 10, 1, 10},
    };
    unsigned k, i, j, fp, ch;
    int rc;
    it2n_par u;

    (void)load_paper(wk, o);
    rc = it2n_dataset_check(&wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
    it2n_model_init(&wk->a);
    rc = it2n_model_solve(&wk->a, &wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
    if (rc != IT2N_OK) {
        return;
    }
    /* The paper model's control nets in full: as stored, then in Q24. */
    out(o, "paper.net_hash", as_i64(hash_ctrl(&wk->a)));
    for (i = 0; i <= 3u; i++) {
        for (j = 0; j <= 3u; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    if (ch != IT2N_CH_Z) {
                        out(o, "paper.ctrl",
                            it2n_model_ctrl(&wk->a, i, j, fp, ch));
                    }
                }
            }
        }
    }
    for (k = 0; k < sizeof at / sizeof at[0]; k++) {
        eval_at(wk, o, &wk->a, par(at[k][0], at[k][1]), par(at[k][2], at[k][3]));
    }
    /* A parameter given in decimal, through the core's own parser. */
    rc = it2n_parse_par("0.123456", 8, &u);
    out(o, "paper.parse_par", rc);
    out(o, "paper.parse_par.value", u);
    eval_at(wk, o, &wk->a, u, par(654321, 1000000));
    /* Outside [0, 1]: an error, not an extrapolation. */
    eval_at(wk, o, &wk->a, IT2N_PAR_ONE + 1, 0);
    eval_at(wk, o, &wk->a, 0, -1);

    deriv_at(wk, o, &wk->a, par(1, 2), par(1, 2));
    deriv_at(wk, o, &wk->a, par(1, 5), par(9, 10));
    deriv_at(wk, o, &wk->a, 0, IT2N_PAR_ONE);

    /* Locate: a data point, a point inside the D surface, far outside. */
    locate_at(wk, o, &wk->a, Q24(-7), Q24(7));
    locate_at(wk, o, &wk->a, Q24(3) + IT2N_VAL_ONE / 3, Q24(-2) - IT2N_VAL_ONE / 7);
    locate_at(wk, o, &wk->a, Q24(100), Q24(100));

    sample_grid(wk, o, &wk->a, 5, 4, 0);
    sample_grid(wk, o, &wk->a, 2, 2, 0);
    sample_grid(wk, o, &wk->a, 3, 3, 4); /* callback stops early */
    sample_grid(wk, o, &wk->a, 1, 3, 0); /* rows < 2: rejected */
}

/* Incremental update against a full re-solve on the paper model (left in
 * wk->a, its data set in wk->ds, by scen_paper). The update changes the
 * model and its data set (wk->b, wk->ds2) together. */
static void scen_update(it2n_vec_work *wk, const vec_out *o)
{
    it2n_val v[IT2N_CH_COUNT];
    uint64_t before;
    it2n_val maxdiff = 0;
    unsigned i, j, fp, ch;
    int rc;

    if (!wk->a.solved) {
        out(o, "update.skipped", 1);
        return;
    }
    wk->b = wk->a;
    wk->ds2 = wk->ds;
    /* (1, 2, L): memberships change, x moves within its neighbours. */
    it2n_dataset_get(&wk->ds, 1, 2, IT2N_FP_L, v);
    v[IT2N_CH_X] += IT2N_VAL_ONE / 2;
    v[IT2N_CH_T] = IT2N_VAL_ONE / 8;
    v[IT2N_CH_I] = IT2N_VAL_ONE - 1;
    v[IT2N_CH_F] = 0;
    rc = it2n_model_update(&wk->b, &wk->ds2, 1, 2, IT2N_FP_L, v, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "update.ctrl_hash", as_i64(hash_ctrl(&wk->b)));
    out(o, "update.ctrl_q24_hash", as_i64(hash_ctrl_q24(&wk->b)));
    eval_at(wk, o, &wk->b, par(1, 2), par(1, 2));
    eval_at(wk, o, &wk->b, par(1, 3), par(2, 3));

    /* The same change as a full re-solve: the same data set and the same
     * nets, bit for bit. */
    rc = it2n_dataset_put(&wk->ds, 1, 2, IT2N_FP_L, v, true, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "update.data_vs_put", same_data(&wk->ds, &wk->ds2));
    it2n_model_init(&wk->a);
    rc = it2n_model_solve(&wk->a, &wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "update.resolve_hash", as_i64(hash_ctrl(&wk->a)));
    for (i = 0; i <= 3u; i++) {
        for (j = 0; j <= 3u; j++) {
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    it2n_val d = it2n_model_ctrl(&wk->a, i, j, fp, ch) -
                                 it2n_model_ctrl(&wk->b, i, j, fp, ch);
                    d = d < 0 ? -d : d;
                    maxdiff = d > maxdiff ? d : maxdiff;
                }
            }
        }
    }
    out(o, "update.max_lsb_vs_resolve", maxdiff);

    /* Rejected updates change nothing (model nor data set). */
    before = hash_ctrl(&wk->b);
    v[IT2N_CH_T] = IT2N_VAL_ONE + 1;
    rc = it2n_model_update(&wk->b, &wk->ds2, 1, 2, IT2N_FP_L, v, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "update.unchanged", hash_ctrl(&wk->b) == before);
    out(o, "update.data_unchanged", same_data(&wk->ds, &wk->ds2));
    v[IT2N_CH_T] = 0;
    v[IT2N_CH_X] = Q24(50); /* beyond R of the same point: not nested */
    rc = it2n_model_update(&wk->b, &wk->ds2, 1, 2, IT2N_FP_L, v, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "update.unchanged", hash_ctrl(&wk->b) == before);
    out(o, "update.data_unchanged", same_data(&wk->ds, &wk->ds2));
    rc = it2n_model_update(&wk->b, &wk->ds2, 4, 0, IT2N_FP_L, v, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "update.unchanged", hash_ctrl(&wk->b) == before);
    out(o, "update.data_unchanged", same_data(&wk->ds, &wk->ds2));
}

/* Generated models: solve, evaluate, differentiate, sample. */
static void scen_generated(it2n_vec_work *wk, const vec_out *o, unsigned n,
                           unsigned m, unsigned flags, uint32_t seed)
{
    int rc;
    if (n > IT2N_MAX_DEGREE || m > IT2N_MAX_DEGREE) {
        return; /* vectors are generated for the default IT2N_MAX_DEGREE */
    }
    rc = make_grid(&wk->ds, n, m, flags, seed, &wk->err);
    out_err(o, rc, &wk->err);
    if (rc != IT2N_OK) {
        return;
    }
    it2n_model_init(&wk->a);
    rc = it2n_model_solve(&wk->a, &wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
    if (rc != IT2N_OK) {
        return;
    }
    if (flags & IT2N_F_CHORD) {
        unsigned k;
        rc = it2n_params(&wk->ds, wk->u, wk->w, &wk->err);
        out_err(o, rc, &wk->err);
        for (k = 0; k <= n; k++) {
            out(o, "chord.u", wk->u[k]);
        }
        for (k = 0; k <= m; k++) {
            out(o, "chord.w", wk->w[k]);
        }
    }
    out(o, "gen.ctrl_hash", as_i64(hash_ctrl(&wk->a)));
    eval_at(wk, o, &wk->a, 0, 0);
    eval_at(wk, o, &wk->a, IT2N_PAR_ONE, IT2N_PAR_ONE);
    eval_at(wk, o, &wk->a, par(2, 7), par(5, 9));
    deriv_at(wk, o, &wk->a, par(3, 8), par(1, 3));
    locate_at(wk, o, &wk->a, Q24(5 * (int)n), Q24(5 * (int)m));
    sample_grid(wk, o, &wk->a, 4, 3, 0);
}

/* Chord-length update (the model of the previous scenario, wk->a, solved
 * from wk->ds): parameters follow footprint D, so every net moves; the
 * result must equal a full re-solve of the changed data. */
static void scen_chord_update(it2n_vec_work *wk, const vec_out *o)
{
    it2n_val v[IT2N_CH_COUNT];
    int rc;
    if (!wk->a.solved || !(wk->a.flags & IT2N_F_CHORD)) {
        out(o, "chord_update.skipped", 1);
        return;
    }
    it2n_dataset_get(&wk->ds, 1, 1, IT2N_FP_D, v);
    v[IT2N_CH_X] += IT2N_VAL_ONE / 4;
    v[IT2N_CH_T] = IT2N_VAL_ONE / 2;
    rc = it2n_model_update(&wk->a, &wk->ds, 1, 1, IT2N_FP_D, v, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "chord_update.ctrl_hash", as_i64(hash_ctrl(&wk->a)));
    rc = it2n_params(&wk->ds, wk->u, wk->w, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "chord_update.u1", wk->u[1]);
    it2n_model_init(&wk->b);
    rc = it2n_model_solve(&wk->b, &wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "chord_update.resolve_same",
        memcmp(wk->a.net, wk->b.net, sizeof wk->a.net) == 0 &&
            memcmp(wk->a.frac, wk->b.frac, sizeof wk->a.frac) == 0);
}

/* Bad input: clear error reports, nothing changed. */
static void scen_errors(it2n_vec_work *wk, const vec_out *o)
{
    it2n_val v[IT2N_CH_COUNT];
    int rc;

    rc = it2n_dataset_init(&wk->ds, 0, 3, 0, &wk->err);
    out_err(o, rc, &wk->err);
    rc = it2n_dataset_init(&wk->ds, 2, IT2N_MAX_DEGREE + 1u, 0, &wk->err);
    out_err(o, rc, &wk->err);
    rc = it2n_dataset_init(&wk->ds, 2, 1, 0x80u, &wk->err);
    out_err(o, rc, &wk->err);

    rc = it2n_dataset_init(&wk->ds, 2, 1, 0, &wk->err);
    out_err(o, rc, &wk->err);
    v[IT2N_CH_X] = Q24(1);
    v[IT2N_CH_Y] = Q24(2);
    v[IT2N_CH_Z] = 0;
    v[IT2N_CH_T] = IT2N_VAL_ONE + IT2N_VAL_ONE / 5; /* T = 1.2 */
    v[IT2N_CH_I] = 0;
    v[IT2N_CH_F] = 0;
    rc = it2n_dataset_put(&wk->ds, 2, 1, IT2N_FP_RL, v, false, &wk->err);
    out_err(o, rc, &wk->err);
    if (rc < 0) {
        out(o, "err.value", wk->err.value);
        out(o, "err.lo", wk->err.lo);
        out(o, "err.hi", wk->err.hi);
    }
    out(o, "errors.missing", it2n_dataset_missing(&wk->ds));
    v[IT2N_CH_T] = IT2N_VAL_ONE;
    rc = it2n_dataset_put(&wk->ds, 2, 1, IT2N_FP_RL, v, false, &wk->err);
    out_err(o, rc, &wk->err);
    rc = it2n_dataset_put(&wk->ds, 2, 1, IT2N_FP_RL, v, false, &wk->err);
    out_err(o, rc, &wk->err); /* duplicate */
    rc = it2n_dataset_put(&wk->ds, 3, 1, IT2N_FP_RL, v, false, &wk->err);
    out_err(o, rc, &wk->err); /* index */
    rc = it2n_dataset_put(&wk->ds, 0, 0, IT2N_FP_COUNT, v, false, &wk->err);
    out_err(o, rc, &wk->err); /* footprint */
    v[IT2N_CH_X] = Q24(IT2N_COORD_LIMIT) + IT2N_VAL_ONE;
    rc = it2n_dataset_put(&wk->ds, 0, 0, IT2N_FP_D, v, false, &wk->err);
    out_err(o, rc, &wk->err); /* coordinate limit */
    out(o, "errors.missing", it2n_dataset_missing(&wk->ds));
    rc = it2n_dataset_check(&wk->ds, &wk->err);
    out_err(o, rc, &wk->err); /* incomplete */
    it2n_model_init(&wk->b);
    rc = it2n_model_solve(&wk->b, &wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
    out(o, "errors.solved", wk->b.solved);
    eval_at(wk, o, &wk->b, 0, 0); /* unsolved model */

    /* Nesting broken on y at (1, 1): LR above L. */
    rc = make_grid(&wk->ds, 2, 2, 0, 99u, &wk->err);
    out_err(o, rc, &wk->err);
    it2n_dataset_get(&wk->ds, 1, 1, IT2N_FP_LR, v);
    v[IT2N_CH_Y] = it2n_dataset_value(&wk->ds, 1, 1, IT2N_FP_L, IT2N_CH_Y) + 1;
    rc = it2n_dataset_put(&wk->ds, 1, 1, IT2N_FP_LR, v, true, &wk->err);
    out_err(o, rc, &wk->err);
    rc = it2n_dataset_check(&wk->ds, &wk->err);
    out_err(o, rc, &wk->err);

    /* Degenerate chord-length parameters: every point in one place. */
    rc = it2n_dataset_init(&wk->ds, 1, 1, IT2N_F_TYPE1 | IT2N_F_CHORD, &wk->err);
    out_err(o, rc, &wk->err);
    v[IT2N_CH_X] = 0;
    v[IT2N_CH_Y] = 0;
    v[IT2N_CH_T] = IT2N_VAL_ONE / 2;
    (void)it2n_dataset_put(&wk->ds, 0, 0, IT2N_FP_D, v, false, &wk->err);
    (void)it2n_dataset_put(&wk->ds, 0, 1, IT2N_FP_D, v, false, &wk->err);
    (void)it2n_dataset_put(&wk->ds, 1, 0, IT2N_FP_D, v, false, &wk->err);
    (void)it2n_dataset_put(&wk->ds, 1, 1, IT2N_FP_D, v, false, &wk->err);
    rc = it2n_model_solve(&wk->b, &wk->ds, &wk->err);
    out_err(o, rc, &wk->err);
}

/* Text conversion: exact decimal parsing and formatting, no libc. */
static void scen_text(const vec_out *o)
{
    static const char *const num[] = {
        "0", "-12.5", "0.000001", "3e-2", "0.4", "-0.7", "1", "8388607",
        "-8388607", "8388608", "1e7", "abc", "", "1.", ".5", "-", "1e", "0.00000002980232238769531250",
    };
    static const int64_t fmt[] = {
        0, 1, -1, IT2N_VAL_ONE, -IT2N_VAL_ONE / 3, 6710886, (int64_t)8388607 << 24,
    };
    char buf[48];
    unsigned k, d;
    for (k = 0; k < sizeof num / sizeof num[0]; k++) {
        it2n_val v = 0;
        int rc = it2n_parse_val(num[k], vec_len(num[k]), &v);
        out(o, "parse_val.rc", rc);
        if (rc == IT2N_OK) {
            out(o, "parse_val.value", v);
        }
    }
    for (k = 0; k < sizeof num / sizeof num[0]; k++) {
        it2n_val v = 0;
        int rc = it2n_parse_memb(num[k], vec_len(num[k]), &v);
        out(o, "parse_memb.rc", rc);
        if (rc == IT2N_OK) {
            out(o, "parse_memb.value", v);
        }
    }
    for (k = 0; k < sizeof fmt / sizeof fmt[0]; k++) {
        for (d = 0; d <= 9u; d += 3u) {
            uint64_t h = VEC_FNV_INIT;
            int len = it2n_format_val(buf, sizeof buf, fmt[k], d);
            int c;
            out(o, "format_val.len", len);
            for (c = 0; c < len; c++) {
                h = hash_i64(h, (unsigned char)buf[c]);
            }
            out(o, "format_val.hash", as_i64(h));
        }
    }
    out(o, "format_val.small_buf", it2n_format_val(buf, 3, IT2N_VAL_ONE * 1000, 6));
    for (k = 0; k <= IT2N_FP_COUNT; k++) {
        const char *name = it2n_fp_name(k);
        out(o, "fp_name.null", name == NULL);
        if (name != NULL) {
            out(o, "fp_from_name", it2n_fp_from_name(name, vec_len(name)));
        }
    }
    out(o, "fp_from_name.bad", it2n_fp_from_name("LX", 2));
}

/* ---- B-spline kind --------------------------------------------------- */

/* Hash of a B-spline model's exponents and every coefficient mantissa. */
static uint64_t hash_bs(const it2n_bspline_model *mdl)
{
    uint64_t h = VEC_FNV_INIT;
    size_t k, words = IT2N_BSPLINE_MODEL_WORDS(mdl->n, mdl->m, mdl->flags);
    unsigned fp, ch;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            h = hash_i64(h, mdl->frac[fp][ch]);
        }
    }
    for (k = 0; k < words; k++) {
        h = hash_i64(h, mdl->coef[k]);
    }
    return h;
}

/* As make_grid for the B-spline data set (n, m intervals); extreme
 * alternates +-IT2N_COORD_LIMIT and memberships 0/1 instead; faint
 * memberships are a few units of 2^-30 (nets of exponent 27 and more: the
 * ARMv7-M kernels' shift from the high word). */
static int make_bs_grid(it2n_vec_work *wk, unsigned n, unsigned m,
                        unsigned flags, uint32_t seed, bool extreme, bool faint)
{
    unsigned i, j, fp;
    int rc = it2n_bspline_data_init(&wk->bs_ds, wk->bs_rec, VEC_BS_RECS, n, m,
                                    flags, &wk->err);
    for (i = 0; i <= n && rc == IT2N_OK; i++) {
        for (j = 0; j <= m && rc == IT2N_OK; j++) {
            it2n_val jx = (it2n_val)(lcg(&seed) >> 2) - ((it2n_val)1 << 21);
            it2n_val jy = (it2n_val)(lcg(&seed) >> 2) - ((it2n_val)1 << 21);
            it2n_val mem[3];
            unsigned k;
            for (k = 0; k < 3u; k++) {
                /* Q30 as generated data sets above */
                mem[k] = extreme ? (it2n_val)((i + 2u * j + k) & 1u) * IT2N_MEMB_ONE
                         : faint ? (it2n_val)(lcg(&seed) >> 26) << k
                                 : ((IT2N_VAL_ONE / 20) + (((it2n_val)lcg(&seed) * 9) / 10)) * 64 +
                                       (it2n_val)((k * 21u + i * 7u + j * 13u) & 63u);
            }
            for (fp = 0; fp < IT2N_FP_COUNT && rc == IT2N_OK; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                it2n_val off = ((it2n_val)fp - IT2N_FP_D) * (3 * IT2N_VAL_ONE / 2);
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
                    continue;
                }
                if (extreme) {
                    it2n_val lim = Q24(IT2N_COORD_LIMIT);
                    v[IT2N_CH_X] = ((i + j) & 1u) ? lim : -lim;
                    v[IT2N_CH_Y] = ((i + j + 1u) & 1u) ? lim : -lim;
                    v[IT2N_CH_Z] = (i & 1u) ? lim : -lim;
                } else {
                    v[IT2N_CH_X] = Q24(10 * (int)i) + jx + off;
                    v[IT2N_CH_Y] = Q24(10 * (int)j) + jy + off;
                    v[IT2N_CH_Z] = Q24((int)(i * j)) / 4 + off / 3;
                }
                v[IT2N_CH_T] = mem[0];
                v[IT2N_CH_I] = mem[1];
                v[IT2N_CH_F] = mem[2];
                rc = it2n_bspline_data_put_fine(&wk->bs_ds, i, j, fp, v, false, &wk->err);
            }
        }
    }
    return rc;
}

/* it2n_bspline_sample sink: hash every node. */
typedef struct bs_sample_state {
    uint64_t hash;
} bs_sample_state;

static int bs_sample_cb(void *ctx, unsigned r, unsigned c, it2n_par u,
                        it2n_par w, const it2n_point *pt)
{
    bs_sample_state *s = ctx;
    unsigned fp, ch;
    s->hash = hash_i64(s->hash, (int64_t)(r * 65536u + c));
    s->hash = hash_i64(s->hash, u ^ w);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            s->hash = hash_i64(s->hash, pt->v[fp][ch]);
        }
    }
    s->hash = hash_i64(s->hash, (int64_t)pt->out_of_range);
    return 0;
}

/* Solve, coefficients, queries (values, summary, derivatives) on several
 * grids; one update against a full re-solve; the extremes. */
static void scen_bspline_one(it2n_vec_work *wk, const vec_out *o, unsigned n,
                             unsigned m, unsigned flags, uint32_t seed,
                             bool extreme, bool faint)
{
    static const uint32_t at[][4] = {{0, 1, 0, 1}, {1, 1, 1, 1}, {1, 2, 1, 3},
                                     {5, 7, 2, 9}, {99, 100, 1, 100},
                                     {1, 3, 1, 1}, {12, 13, 7, 11}};
    bs_sample_state ss;
    unsigned k, fp, ch;
    int rc = make_bs_grid(wk, n, m, flags, seed, extreme, faint);
    out(o, "bs.put", rc);
    it2n_bspline_model_init(&wk->bs_a, wk->bs_coef, VEC_BS_WORDS);
    rc = it2n_bspline_solve(&wk->bs_a, &wk->bs_ds, &wk->err);
    out(o, "bs.solve", rc);
    if (rc != IT2N_OK) {
        out_errinfo(o, rc, &wk->err);
        return;
    }
    out(o, "bs.hash", as_i64(hash_bs(&wk->bs_a)));
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        out(o, "bs.coef", it2n_bspline_coef(&wk->bs_a, 1, m + 1u, IT2N_FP_D, ch));
    }
    for (k = 0; k < sizeof at / sizeof at[0]; k++) {
        it2n_par u = par(at[k][0], at[k][1]), w = par(at[k][2], at[k][3]);
        uint64_t h = VEC_FNV_INIT;
        rc = it2n_bspline_eval(&wk->bs_a, u, w, &wk->pt, &wk->err);
        out(o, "bs.eval", rc);
        for (fp = 0; fp < IT2N_FP_COUNT && rc == IT2N_OK; fp++) {
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                h = hash_i64(h, wk->pt.v[fp][ch]);
            }
        }
        for (ch = 0; ch < 3u && rc == IT2N_OK; ch++) {
            h = hash_i64(h, wk->pt.sum.upper_min[ch]);
            h = hash_i64(h, wk->pt.sum.upper_max[ch]);
            h = hash_i64(h, wk->pt.sum.lower_min[ch]);
            h = hash_i64(h, wk->pt.sum.lower_max[ch]);
        }
        out(o, "bs.eval_hash", as_i64(hash_i64(h, (int64_t)wk->pt.out_of_range)));
        out(o, "bs.eval_D_T", wk->pt.v[IT2N_FP_D][IT2N_CH_T]);
        rc = it2n_bspline_deriv(&wk->bs_a, u, w, &wk->du, &wk->dw, &wk->err);
        out(o, "bs.deriv", rc);
        h = VEC_FNV_INIT;
        for (fp = 0; fp < IT2N_FP_COUNT && rc == IT2N_OK; fp++) {
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                h = hash_i64(h, wk->du.v[fp][ch]);
                h = hash_i64(h, wk->dw.v[fp][ch]);
            }
        }
        out(o, "bs.deriv_hash", as_i64(h));
    }
    /* locate the D point at (5/7, 2/9) */
    rc = it2n_bspline_eval(&wk->bs_a, par(5, 7), par(2, 9), &wk->pt, &wk->err);
    if (rc == IT2N_OK) {
        uint64_t h = VEC_FNV_INIT;
        rc = it2n_bspline_locate(&wk->bs_a, wk->pt.v[IT2N_FP_D][IT2N_CH_X],
                                 wk->pt.v[IT2N_FP_D][IT2N_CH_Y], &wk->loc, &wk->err);
        for (fp = 0; fp < IT2N_FP_COUNT && rc == IT2N_OK; fp++) {
            h = hash_i64(h, wk->loc.fp[fp].u);
            h = hash_i64(h, wk->loc.fp[fp].w);
            h = hash_i64(h, wk->loc.fp[fp].residual);
            h = hash_i64(h, wk->loc.fp[fp].status);
            for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
                h = hash_i64(h, wk->loc.fp[fp].v[ch]);
            }
        }
        out(o, "bs.locate", rc);
        out(o, "bs.locate_hash", as_i64(h));
    }
    ss.hash = VEC_FNV_INIT;
    rc = it2n_bspline_sample(&wk->bs_a, 9, 6, bs_sample_cb, &ss, &wk->err);
    out(o, "bs.sample", rc);
    out(o, "bs.sample_hash", as_i64(ss.hash));
    if (extreme) {
        return;
    }
    /* update one footprint of one point; compare with a full re-solve */
    {
        it2n_val v[IT2N_CH_COUNT];
        unsigned fu = (flags & IT2N_F_TYPE1) ? IT2N_FP_D : IT2N_FP_L;
        it2n_bspline_data_get_fine(&wk->bs_ds, n / 2u, m / 3u, fu, v);
        v[IT2N_CH_T] = IT2N_MEMB_ONE - v[IT2N_CH_T];
        v[IT2N_CH_X] += IT2N_VAL_ONE / 3;
        rc = it2n_bspline_update_fine(&wk->bs_a, &wk->bs_ds, n / 2u, m / 3u, fu, v,
                                      &wk->err);
        out(o, "bs.update", rc);
        out(o, "bs.update_hash", as_i64(hash_bs(&wk->bs_a)));
        it2n_bspline_model_init(&wk->bs_b, wk->bs_coef2, VEC_BS_WORDS);
        rc = it2n_bspline_solve(&wk->bs_b, &wk->bs_ds, &wk->err);
        out(o, "bs.resolve", rc);
        out(o, "bs.same", hash_bs(&wk->bs_a) == hash_bs(&wk->bs_b) &&
                          memcmp(wk->bs_coef, wk->bs_coef2,
                                 IT2N_BSPLINE_MODEL_WORDS(n, m, flags) * 4u) == 0);
    }
}

static void scen_bspline(it2n_vec_work *wk, const vec_out *o)
{
    scen_bspline_one(wk, o, 10, 7, 0, 21u, false, false);              /* type-2 */
    scen_bspline_one(wk, o, 20, 20, IT2N_F_TYPE1 | IT2N_F_Z, 22u, false, false);
    scen_bspline_one(wk, o, 1, 2, IT2N_F_Z, 23u, false, false);        /* line, parabola */
    scen_bspline_one(wk, o, 3, 4, IT2N_F_TYPE1, 24u, false, false);    /* 4 points: a cubic */
    scen_bspline_one(wk, o, 9, 5, IT2N_F_Z, 25u, true, false);         /* +-limit */
    /* faint memberships, both kinds and both type-1 layouts */
    scen_bspline_one(wk, o, 5, 6, IT2N_F_TYPE1 | IT2N_F_Z, 26u, false, true);
    scen_bspline_one(wk, o, 6, 4, IT2N_F_TYPE1, 27u, false, true);
    scen_bspline_one(wk, o, 4, 5, IT2N_F_Z, 28u, false, true);
}

void it2n_vec_scenarios(it2n_vec_work *wk, it2n_vec_put put, void *state)
{
    /* Degree pairs: the extremes, non-square grids, the default maximum. */
    static const uint8_t pairs[][2] = {
        {1, 1}, {1, 7}, {7, 1}, {2, 3}, {3, 3}, {4, 6}, {5, 2}, {6, 6}, {7, 7},
    };
    vec_out o;
    unsigned k;

    o.put = put;
    o.state = state;
    memset(wk, 0, sizeof *wk);

    scen_paper(wk, &o);
    scen_update(wk, &o);
    for (k = 0; k < sizeof pairs / sizeof pairs[0]; k++) {
        scen_generated(wk, &o, pairs[k][0], pairs[k][1], 0, 1000u + k);
    }
    scen_generated(wk, &o, 3, 2, IT2N_F_TYPE1, 7u);                /* type-1 */
    scen_generated(wk, &o, 3, 3, IT2N_F_Z, 8u);                    /* z      */
    scen_generated(wk, &o, 4, 3, IT2N_F_CHORD, 9u);                /* chord  */
    scen_chord_update(wk, &o);
    scen_generated(wk, &o, 2, 5, IT2N_F_Z | IT2N_F_CHORD | IT2N_F_TYPE1, 10u);
    scen_errors(wk, &o);
    scen_text(&o);
    /* appended (issue 21): the vectors before these are unchanged */
    scen_bspline(wk, &o);
}
