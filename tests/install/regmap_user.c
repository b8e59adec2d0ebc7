/* regmap_user — a consumer of the installed register map library
 * (pkg-config it2n-regmap, pkg-install): encodes a value the way a PLC
 * reads it and finds a block by address, printing what it got. */
#include <stdio.h>

#include "it2n_regmap.h"

int main(void)
{
    uint16_t r[2];
    const it2n_regmap_block *b = it2n_regmap_find(IT2N_REGMAP_REG_GRID, 3);
    it2n_regmap_put_f32(r, 1.5f, IT2N_REGMAP_WO_CDAB); /* 1.5f = 0x3FC00000 */
    printf("%04x %04x %s %u\n", r[0], r[1], b ? b->name : "-", it2n_regmap_par_to_u16((int64_t)1 << 31));
    return 0;
}
