/* mb_rtu — Modbus RTU slaves on serial devices ([rtu:NAME] sections), one
 * libmodbus RTU context per port. Frames are assembled in the loop from
 * non-blocking reads (length from the function code, CRC checked here),
 * then answered with modbus_reply on the port's context. */
#ifndef IT2ND_MB_RTU_H
#define IT2ND_MB_RTU_H

#include "conf.h"
#include "mb_map.h"

int mb_rtu_start(const struct conf *c, const struct mb_map_opts *o);
int mb_rtu_reload(const struct conf *c, const struct mb_map_opts *o);
void mb_rtu_release(int commit_ok);
/* The same for the replies waiting for WAL batches up to `batch`. */
void mb_rtu_release_upto(uint64_t batch, int commit_ok);
void mb_rtu_stop(void);

#endif
