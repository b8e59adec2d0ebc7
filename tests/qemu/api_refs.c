/*
 * Entry point for the `make cross` link: references every public core
 * function so that --gc-sections keeps exactly what an application using the
 * whole API would link, and the link proves every symbol resolves with only
 * libgcc and memcpy/memset/memmove.
 */
#include "it2n.h"

typedef void (*it2n_any_fn)(void);

void it2n_cross_entry(void);

/* Casts between function pointer types are fine: nothing calls through. */
static const volatile it2n_any_fn it2n_api[] = {
    (it2n_any_fn)it2n_dataset_init, (it2n_any_fn)it2n_dataset_put,
    (it2n_any_fn)it2n_dataset_get, (it2n_any_fn)it2n_dataset_missing,
    (it2n_any_fn)it2n_dataset_check,
    (it2n_any_fn)it2n_model_init, (it2n_any_fn)it2n_model_solve,
    (it2n_any_fn)it2n_model_update, (it2n_any_fn)it2n_model_ctrl,
    (it2n_any_fn)it2n_params, (it2n_any_fn)it2n_eval,
    (it2n_any_fn)it2n_deriv, (it2n_any_fn)it2n_sample,
    (it2n_any_fn)it2n_locate, (it2n_any_fn)it2n_parse_val,
    (it2n_any_fn)it2n_parse_par, (it2n_any_fn)it2n_format_val,
    (it2n_any_fn)it2n_format_par, (it2n_any_fn)it2n_fp_name,
    (it2n_any_fn)it2n_fp_from_name, (it2n_any_fn)it2n_ch_name,
    (it2n_any_fn)it2n_strerror,
    (it2n_any_fn)it2n_bspline_data_init, (it2n_any_fn)it2n_bspline_data_put,
    (it2n_any_fn)it2n_bspline_data_get, (it2n_any_fn)it2n_bspline_data_missing,
    (it2n_any_fn)it2n_bspline_data_check, (it2n_any_fn)it2n_bspline_model_init,
    (it2n_any_fn)it2n_bspline_solve, (it2n_any_fn)it2n_bspline_update,
    (it2n_any_fn)it2n_bspline_coef, (it2n_any_fn)it2n_bspline_eval,
    (it2n_any_fn)it2n_bspline_deriv, (it2n_any_fn)it2n_bspline_sample,
    (it2n_any_fn)it2n_bspline_locate,
    (it2n_any_fn)it2n_dataset_put_fine, (it2n_any_fn)it2n_dataset_get_fine,
    (it2n_any_fn)it2n_model_update_fine, (it2n_any_fn)it2n_bspline_data_put_fine,
    (it2n_any_fn)it2n_bspline_data_get_fine, (it2n_any_fn)it2n_bspline_update_fine,
    (it2n_any_fn)it2n_parse_memb,
};

void it2n_cross_entry(void)
{
    size_t k;
    for (k = 0; k < sizeof it2n_api / sizeof it2n_api[0]; k++) {
        (void)it2n_api[k];
    }
    for (;;) {
    }
}
