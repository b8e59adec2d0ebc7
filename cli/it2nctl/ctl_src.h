/*
 * What it2nctl push uploads, whichever the transport (ctl_link.c,
 * ctl_modbus.c): a Bezier data set or a B-spline one, read through one set
 * of accessors so both transports walk the same entries.
 */
#ifndef IT2N_CTL_SRC_H
#define IT2N_CTL_SRC_H

#include "it2n.h"

#include <stdbool.h>

/* Exactly one of ds (Bezier) and bds (B-spline) is set. */
typedef struct ctl_src {
    const it2n_dataset *ds;
    const it2n_bspline_data *bds;
} ctl_src;

/* Grid size (i in 0..n, j in 0..m) and IT2N_F_* flags of the data. */
unsigned ctl_src_n(const ctl_src *s);
unsigned ctl_src_m(const ctl_src *s);
unsigned ctl_src_flags(const ctl_src *s);

/* True if entry (i, j, fp) is present (a type-1 set holds D only). */
bool ctl_src_has(const ctl_src *s, unsigned i, unsigned j, unsigned fp);

/* Entry (i, j, fp) with memberships in Q24 (ctl_src_get) or as stored, in
 * Q30 (ctl_src_get_fine). */
void ctl_src_get(const ctl_src *s, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT]);
void ctl_src_get_fine(const ctl_src *s, unsigned i, unsigned j, unsigned fp, it2n_val v[IT2N_CH_COUNT]);

#endif
