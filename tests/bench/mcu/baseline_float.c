/* The float baseline (see baseline.h). */
#include "baseline.h"

#define BL_T float
#define BL_P blf
#include "baseline_impl.h"
