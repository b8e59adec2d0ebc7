/* errs — it2nd's own error codes, for failures that are the daemon's and
 * not the data's: the state directory failed an I/O call, memory ran out,
 * the store is degraded. Negative and disjoint from the core's
 * (IT2N_ERR_*, -1..-10) and the protocol's (IT2N_PROTO_ERR_*, -100..);
 * they reach PLCs in the status block's last_error register (with
 * exception 04) and instruments in NACKs and GET_STATUS. docs/daemon.md. */
#ifndef IT2ND_ERRS_H
#define IT2ND_ERRS_H

enum it2nd_error {
    IT2ND_ERR_IO = -200,      /* the state directory failed a write/fsync: not durable, refused */
    IT2ND_ERR_NOMEM = -201,   /* out of memory: refused, nothing changed                        */
    IT2ND_ERR_DEGRADED = -202 /* store degraded after an I/O error: writes refused until a
                                  checkpoint (snapshot + new WAL) succeeds                        */
};

/* Text for any code: the daemon's, the protocol's or the core's. */
const char *errs_strerror(int code);

#endif
