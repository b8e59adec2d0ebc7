/* An IT2N_CONFIG header as a firmware project would write it: every option
 * in one place (tests/core/test_config.c checks each one took effect). */
#ifndef IT2N_TEST_CONFIG_H
#define IT2N_TEST_CONFIG_H

#define IT2N_MAX_DEGREE 3
#define IT2N_COORD_LIMIT 1000
#define IT2N_LOCATE_GRID 4
#define IT2N_LOCATE_MAX_ITER 20
#define IT2N_CHORD 0
#define IT2N_BSPLINE_MAX_N 15
#define IT2N_ASSERT(c) ((c) ? (void)0 : __builtin_trap())

#endif
