/* fuzz_model_check.h — "never serve wrong data": a SOLVED model's data set
 * (the daemon's md->ds, which the model was solved from and is updated
 * with) validates, the model's degrees and flags are the data set's, and its
 * control nets (exponents and mantissas, every byte) are bit-identical to a
 * fresh solve of that data set. Shared by the fuzzers whose inputs can
 * change models. */
#ifndef FUZZ_DAEMON_MODEL_CHECK_H
#define FUZZ_DAEMON_MODEL_CHECK_H

#include <stdlib.h>
#include <string.h>

#include "fake_env.h"
#include "it2n.h"
#include "it2n_regmap.h"
#include "models.h"

/* The same B-spline data and model (sizes, records, coefficients in use,
 * exponents); true for two Bezier models. */
static inline int fuzz_bs_same(const struct model *a, const struct model *b)
{
    const it2n_bspline_data *x = &a->bds, *y = &b->bds;
    if (a->kind != b->kind)
        return 0;
    if (a->kind != MODEL_BSPLINE)
        return 1;
    return x->n == y->n && x->m == y->m && x->flags == y->flags &&
           memcmp(x->rec, y->rec, IT2N_BSPLINE_DATA_RECS(x->n, x->m, x->flags) * sizeof *x->rec) == 0 &&
           a->bmdl.solved == b->bmdl.solved && a->bmdl.n == b->bmdl.n && a->bmdl.m == b->bmdl.m &&
           a->bmdl.flags == b->bmdl.flags && a->bmdl.generation == b->bmdl.generation &&
           memcmp(a->bmdl.frac, b->bmdl.frac, sizeof a->bmdl.frac) == 0 &&
           (!a->bmdl.solved ||
            memcmp(a->bmdl.coef, b->bmdl.coef,
                   IT2N_BSPLINE_MODEL_WORDS(a->bmdl.n, a->bmdl.m, a->bmdl.flags) * sizeof(int32_t)) == 0);
}

/* "never serve wrong data" for a B-spline model: its data validate and its
 * coefficients equal a fresh solve of them in storage of its own. */
static inline void fuzz_check_bspline(const struct model *md)
{
    const it2n_bspline_data *d = &md->bds;
    it2n_errinfo err;
    fuzz_check(d->n >= 1 && d->n <= md->cap_n && d->m >= 1 && d->m <= md->cap_m, "B-spline sizes in storage");
    fuzz_check(md->state >= IT2N_REGMAP_STATE_EMPTY && md->state <= IT2N_REGMAP_STATE_FAILED, "state in range");
    if (md->state != IT2N_REGMAP_STATE_SOLVED)
        return;
    size_t words = IT2N_BSPLINE_MODEL_WORDS(d->n, d->m, d->flags);
    int32_t *coef = malloc(words * sizeof *coef);
    it2n_bspline_model fresh;
    fuzz_check(coef != NULL, "malloc");
    fuzz_check(it2n_bspline_data_check(d, &err) == IT2N_OK, "served B-spline data pass the check");
    fuzz_check(md->bmdl.solved == 1 && md->bmdl.n == d->n && md->bmdl.m == d->m && md->bmdl.flags == d->flags,
               "B-spline model sizes and flags equal the data set's");
    it2n_bspline_model_init(&fresh, coef, words);
    fuzz_check(it2n_bspline_solve(&fresh, d, &err) == IT2N_OK, "served B-spline data solve");
    fuzz_check(memcmp(fresh.frac, md->bmdl.frac, sizeof fresh.frac) == 0, "B-spline exponents equal a fresh solve");
    fuzz_check(memcmp(coef, md->bmdl.coef, words * sizeof *coef) == 0, "B-spline coefficients equal a fresh solve");
    free(coef);
}

static inline void fuzz_check_model(const struct model *md)
{
    static it2n_model fresh;
    const it2n_model *m = &md->mdl;
    it2n_errinfo err;
    fuzz_note("model %d state %d", md->id, md->state);
    if (md->kind == MODEL_BSPLINE) {
        fuzz_check_bspline(md);
        return;
    }
    fuzz_check(md->ds.n >= 1 && md->ds.n <= IT2N_MAX_DEGREE && md->ds.m >= 1 && md->ds.m <= IT2N_MAX_DEGREE,
               "degrees in range");
    fuzz_check(md->state >= IT2N_REGMAP_STATE_EMPTY && md->state <= IT2N_REGMAP_STATE_FAILED, "state in range");
    if (md->state != IT2N_REGMAP_STATE_SOLVED)
        return;
    fuzz_check((md->ds.flags & ~IT2N_F_ALL) == 0, "flags valid");
    fuzz_check(m->solved == 1, "solved model marked solved");
    fuzz_check(it2n_dataset_check(&md->ds, &err) == IT2N_OK, "served data passes it2n_dataset_check");
    fuzz_check(m->n == md->ds.n && m->m == md->ds.m && m->flags == md->ds.flags,
               "model degrees and flags equal the data set's");
    it2n_model_init(&fresh);
    fuzz_check(it2n_model_solve(&fresh, &md->ds, &err) == IT2N_OK, "served data solves");
    fuzz_check(fresh.n == m->n && fresh.m == m->m && fresh.flags == m->flags && fresh.solved == m->solved,
               "degrees, flags and solved equal a fresh solve");
    fuzz_check(memcmp(fresh.frac, m->frac, sizeof fresh.frac) == 0, "net exponents equal a fresh solve");
    fuzz_check(memcmp(fresh.net, m->net, sizeof fresh.net) == 0, "control nets equal a fresh solve");
}

/* The model table every model-changing fuzzer starts from: room for `max`
 * models, model 1 on unit 1 solved from the paper data, model 2 on unit 2 an
 * empty 2x2 type-1 model, model 3 on unit 3 a B-spline model (storage for
 * 5 x 4 intervals) solved from a 4 x 3 type-2 grid. */
#define FUZZ_STANDARD_MODELS 3
static inline void fuzz_standard_models(int max)
{
    it2n_errinfo err;
    fuzz_check(models_init(max) == 0, "models_init");
    struct model *a = models_add(1, 1, MODEL_BEZIER, 3, 3, 0);
    fuzz_check(a && models_preload_paper(a) == IT2N_OK && a->state == IT2N_REGMAP_STATE_SOLVED, "paper model");
    fuzz_check(models_add(2, 2, MODEL_BEZIER, 2, 2, IT2N_F_TYPE1) != NULL, "model 2");
    struct model *b = models_add(3, 3, MODEL_BSPLINE, 5, 4, 0);
    fuzz_check(b && models_configure(b, 4, 3, 0, &err) == IT2N_OK, "B-spline model 3");
    for (unsigned i = 0; i <= 4; i++)
        for (unsigned j = 0; j <= 3; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT] = { 0 };
                v[IT2N_CH_X] = (it2n_val)i * IT2N_VAL_ONE + (it2n_val)fp * (IT2N_VAL_ONE / 16);
                v[IT2N_CH_Y] = (it2n_val)j * IT2N_VAL_ONE + (it2n_val)fp * (IT2N_VAL_ONE / 16);
                v[IT2N_CH_T] = (it2n_val)((i + j + fp) % 5) * (IT2N_VAL_ONE / 4);
                v[IT2N_CH_I] = (it2n_val)((i * j) % 3) * (IT2N_VAL_ONE / 2);
                v[IT2N_CH_F] = (it2n_val)(fp % 2) * (IT2N_VAL_ONE / 8);
                fuzz_check(models_put(b, i, j, fp, v, false, &err) == IT2N_OK, "B-spline point");
            }
    fuzz_check(b->state == IT2N_REGMAP_STATE_SOLVED, "B-spline model solved");
    models_pass_end(1, NULL, NULL);
}

#endif
