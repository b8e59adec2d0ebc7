/* fuzz_model_check.h — "never serve wrong data": a SOLVED model's data
 * validates, equals its staging data, and its parameters, inverses, control
 * nets and rounding remainders are bit-identical to a fresh solve. Shared
 * by the fuzzers whose inputs can change models. */
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
    fuzz_check(it2n_dataset_check(&m->data, &err) == IT2N_OK, "served data passes it2n_dataset_check");
    fuzz_check(memcmp(&md->ds, &m->data, sizeof md->ds) == 0, "staging data equals the solved data");
    it2n_model_init(&fresh);
    fuzz_check(it2n_model_solve(&fresh, &m->data, &err) == IT2N_OK, "served data solves");
    unsigned n = m->data.n, mm = m->data.m;
    for (unsigned i = 0; i <= n; i++) {
        fuzz_check(fresh.u[i] == m->u[i], "parameter u equals a fresh solve");
        for (unsigned r = 0; r <= n; r++)
            fuzz_check(fresh.ainv[i][r] == m->ainv[i][r], "(M^T)^-1 equals a fresh solve");
    }
    for (unsigned j = 0; j <= mm; j++) {
        fuzz_check(fresh.w[j] == m->w[j], "parameter w equals a fresh solve");
        for (unsigned r = 0; r <= mm; r++)
            fuzz_check(fresh.binv[j][r] == m->binv[j][r], "N^-1 equals a fresh solve");
    }
    for (unsigned i = 0; i <= n; i++)
        for (unsigned j = 0; j <= mm; j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                if (!it2n_model_has_fp(m, fp))
                    continue;
                for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
                    fuzz_check(fresh.ctrl[i][j][fp][ch] == m->ctrl[i][j][fp][ch], "control net equals a fresh solve");
                    fuzz_check(fresh.ctrl_rem[i][j][fp][ch] == m->ctrl_rem[i][j][fp][ch],
                               "control net remainder equals a fresh solve");
                }
            }
}

/* The model table every model-changing fuzzer starts from: room for `max`
 * models, model 1 on unit 1 solved from the paper data, model 2 on unit 2 an
 * empty 2x2 type-1 model. */
static inline void fuzz_standard_models(int max)
{
    fuzz_check(models_init(max) == 0, "models_init");
    struct model *a = models_add(1, 1, 3, 3, 0);
    fuzz_check(a && models_preload_paper(a) == IT2N_OK && a->state == IT2N_RS_SOLVED, "paper model");
    fuzz_check(models_add(2, 2, 2, 2, IT2N_F_TYPE1) != NULL, "model 2");
}

#endif
