/*
 * Compile-time sizes for `make size`: each array's symbol size (nm -S) is the
 * sizeof of one public struct for the configuration this is compiled with.
 * Only compiled (-c), never linked or run.
 */
#include "it2n.h"

char it2n_sizeof_dataset[sizeof(it2n_dataset)];
char it2n_sizeof_model[sizeof(it2n_model)];
char it2n_sizeof_point[sizeof(it2n_point)];
char it2n_sizeof_locate_result[sizeof(it2n_locate_result)];
char it2n_sizeof_errinfo[sizeof(it2n_errinfo)];
