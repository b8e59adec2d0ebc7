/*
 * Entry of the flash-size link (make bench): references only
 * it2n_model_solve, it2n_eval and it2n_locate, so a --gc-sections link keeps
 * exactly the core code a firmware using those three needs.
 */
#include "it2n.h"

typedef void (*bc_any_fn)(void);

void bc_flash_entry(void);

/* Casts between function pointer types are fine: nothing calls through. */
static const volatile bc_any_fn bc_flash_api[] = {
    (bc_any_fn)it2n_model_solve, (bc_any_fn)it2n_eval, (bc_any_fn)it2n_locate,
};

void bc_flash_entry(void)
{
    size_t k;
    for (k = 0; k < sizeof bc_flash_api / sizeof bc_flash_api[0]; k++) {
        (void)bc_flash_api[k];
    }
    for (;;) {
    }
}
