/* The double baseline (see baseline.h). */
#include "baseline.h"

#define BL_T double
#define BL_P bld
#include "baseline_impl.h"
