/* spb_dcmd — a DCMD to a Device model-N (docs/sparkplug.md, "The session"):
 * Query/u and Query/w set the device's query; the 9 Upload metrics are one
 * data point written through the register map's upload path (complete
 * validation, a transaction, the WAL, like a Modbus FC16 of registers
 * 40..51). Anything else refuses the whole command: nothing changes, the
 * reason is logged and set as the model's last_error (-1), as for a
 * refused Modbus write. The caller publishes what moved (DDATA). */
#ifndef IT2ND_SPB_DCMD_H
#define IT2ND_SPB_DCMD_H

#include <stddef.h>
#include <stdint.h>

#include "mb_map.h"
#include "models.h"

/* Apply the DCMD payload buf to md (the live model) with the device's
 * query q and the node's register-map options o (ABCD, grid size,
 * write_protect). */
void spb_dcmd_apply(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const uint8_t *buf,
                    size_t len);

#endif
