/* IT2N_CONFIG of the Cortex-M0+ library build in make test: a small part
 * (grids up to 4x4, no chord-length parameters). Installed next to it2n.h;
 * find_package(it2n) passes -DIT2N_CONFIG=it2n_m0p_config.h to users. */
#ifndef IT2N_M0P_CONFIG_H
#define IT2N_M0P_CONFIG_H

#define IT2N_MAX_DEGREE 3
#define IT2N_CHORD 0

#endif
