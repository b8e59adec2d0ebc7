/*
 * Memory budget of a firmware per IT2N_MAX_DEGREE (docs/firmware.md, figure
 * fw-budget, tests/firmware/fw_budget.py): each array's symbol size
 * (arm-none-eabi-nm -S) is the sizeof of one struct a firmware keeps,
 * compiled once per degree. Only compiled (-c), never linked or run.
 */
#include "it2n_link.h"

char fw_sizeof_dataset[sizeof(it2n_dataset)];
char fw_sizeof_model[sizeof(it2n_model)];
char fw_sizeof_link[sizeof(it2n_link)];
char fw_sizeof_msg[sizeof(it2n_msg)];
char fw_sizeof_point[sizeof(it2n_point)];
