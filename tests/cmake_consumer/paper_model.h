/* The paper's 4x4 example as a type-1 model (see paper_model.c). */
#ifndef PAPER_MODEL_H
#define PAPER_MODEL_H

#include "it2n.h"

/* Solve the model once (IT2N_OK or an IT2N_ERR_* code, err filled). */
int paper_model_solve(it2n_errinfo *err);

/* Footprint D at (u, w) in Q32: x, y, z, T, I, F in Q24. */
int paper_model_eval(it2n_par u, it2n_par w, it2n_val out[IT2N_CH_COUNT],
                     it2n_errinfo *err);

#endif
