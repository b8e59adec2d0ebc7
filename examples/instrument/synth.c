/* Synthetic grid data set (see synth.h). */
#include "synth.h"

static uint32_t xorshift32(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return *s = x;
}

/* Uniform in [0, span) Q24 units, span in Q24. */
static it2n_val frac(uint32_t *s, it2n_val span)
{
    return (it2n_val)((uint64_t)(xorshift32(s) >> 8) * (uint64_t)span >> 24);
}

int synth_dataset(it2n_dataset *ds, unsigned n, unsigned m, unsigned flags, uint32_t seed, it2n_errinfo *err)
{
    uint32_t s = seed * 2654435761u + 0x9E3779B9u;
    unsigned i, j, fp;
    int r = it2n_dataset_init(ds, n, m, flags, err);
    if (r != IT2N_OK)
        return r;
    if (s == 0u)
        s = 1u;
    for (i = 0; i <= n; i++) {
        for (j = 0; j <= m; j++) {
            it2n_val base[IT2N_CH_COUNT], spread;
            base[IT2N_CH_X] = (it2n_val)i * 10 * IT2N_VAL_ONE - IT2N_VAL_ONE + frac(&s, 2 * IT2N_VAL_ONE);
            base[IT2N_CH_Y] = (it2n_val)j * 10 * IT2N_VAL_ONE - IT2N_VAL_ONE + frac(&s, 2 * IT2N_VAL_ONE);
            base[IT2N_CH_Z] = (flags & IT2N_F_Z) ? (it2n_val)(i * (m - j) + 1) * IT2N_VAL_ONE / 2 : 0;
            base[IT2N_CH_T] = frac(&s, IT2N_VAL_ONE + 1);
            base[IT2N_CH_I] = frac(&s, IT2N_VAL_ONE + 1);
            base[IT2N_CH_F] = frac(&s, IT2N_VAL_ONE + 1);
            spread = IT2N_VAL_ONE / 2 + frac(&s, IT2N_VAL_ONE);
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                it2n_val off = ((it2n_val)fp - IT2N_FP_D) * spread;
                if ((flags & IT2N_F_TYPE1) && fp != IT2N_FP_D)
                    continue;
                v[IT2N_CH_X] = base[IT2N_CH_X] + off;
                v[IT2N_CH_Y] = base[IT2N_CH_Y] + off;
                v[IT2N_CH_Z] = (flags & IT2N_F_Z) ? base[IT2N_CH_Z] + off : 0;
                v[IT2N_CH_T] = base[IT2N_CH_T];
                v[IT2N_CH_I] = base[IT2N_CH_I];
                v[IT2N_CH_F] = base[IT2N_CH_F];
                r = it2n_dataset_put(ds, i, j, fp, v, false, err);
                if (r != IT2N_OK)
                    return r;
            }
        }
    }
    return it2n_dataset_check(ds, err);
}
