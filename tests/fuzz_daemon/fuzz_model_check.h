/* fuzz_model_check.h — "never serve wrong data": a SOLVED model's data set
 * (the daemon's md->ds, which the model was solved from and is updated
 * with) validates, the model's degrees and flags are the data set's, and its
 * control nets (exponents and mantissas, every byte) are bit-identical to a
 * fresh solve of that data set. Shared by the fuzzers whose inputs can
 * change models. */
#ifndef FUZZ_DAEMON_MODEL_CHECK_H
#define FUZZ_DAEMON_MODEL_CHECK_H

#include <string.h>

#include "fake_env.h"
#include "it2n.h"
#include "it2n_regmap.h"
#include "models.h"

static inline void fuzz_check_model(const struct model *md)
{
    static it2n_model fresh;
    const it2n_model *m = &md->mdl;
    it2n_errinfo err;
    fuzz_note("model %d state %d", md->id, md->state);
    fuzz_check(md->ds.n >= 1 && md->ds.n <= IT2N_MAX_DEGREE && md->ds.m >= 1 && md->ds.m <= IT2N_MAX_DEGREE,
               "degrees in range");
    fuzz_check(md->state >= IT2N_RS_EMPTY && md->state <= IT2N_RS_FAILED, "state in range");
    if (md->state != IT2N_RS_SOLVED)
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
 * empty 2x2 type-1 model. */
static inline void fuzz_standard_models(int max)
{
    fuzz_check(models_init(max) == 0, "models_init");
    struct model *a = models_add(1, 1, MODEL_BEZIER, 3, 3, 0);
    fuzz_check(a && models_preload_paper(a) == IT2N_OK && a->state == IT2N_RS_SOLVED, "paper model");
    fuzz_check(models_add(2, 2, MODEL_BEZIER, 2, 2, IT2N_F_TYPE1) != NULL, "model 2");
}

#endif
