/* errs.c — see errs.h. */
#include "errs.h"

#include "it2n.h"
#include "it2n_proto.h"

const char *errs_strerror(int code)
{
    switch (code) {
    case IT2ND_ERR_IO: return "I/O error in the state directory (not durable)";
    case IT2ND_ERR_NOMEM: return "out of memory";
    case IT2ND_ERR_DEGRADED: return "store degraded after an I/O error (writes refused until a checkpoint succeeds)";
    default: return code <= IT2N_PROTO_ERR_COBS ? it2n_proto_strerror(code) : it2n_strerror(code);
    }
}
