/* Synthetic "measurement" of an (n+1) x (m+1) grid, integer arithmetic only. */
#ifndef INSTRUMENT_SYNTH_H
#define INSTRUMENT_SYNTH_H

#include "it2n.h"

/*
 * Fill ds (initialised here) with a deterministic data set for seed: a
 * jittered grid with spacing 10 units, seven nested footprints around each
 * point (spread 0.5..1.5 units per step), z a bilinear bump when
 * IT2N_F_Z, memberships T, I, F in [0, 1] shared by a point's footprints.
 * Returns IT2N_OK or the core's error (err filled).
 */
int synth_dataset(it2n_dataset *ds, unsigned n, unsigned m, unsigned flags, uint32_t seed, it2n_errinfo *err);

#endif
