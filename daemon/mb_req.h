/* mb_req — one Modbus request (a complete ADU, TCP or RTU) against the
 * model table: decode, check counts, run mb_map, answer: the reply framed
 * here (as modbus_reply() frames it) and sent at once (TCP: loop_send(),
 * exceptions framed here too; RTU: libmodbus adds the CRC, exceptions with
 * modbus_reply_exception()). A
 * request that changed a model is held until the WAL commit (group commit)
 * and answered by mb_req_release(). */
#ifndef IT2ND_MB_REQ_H
#define IT2ND_MB_REQ_H

#include <modbus.h>
#include <stdint.h>

#include "mb_map.h"

struct mb_req_session {
    modbus_t *ctx; /* one per connection / serial port */
    int is_tcp;
    int read_only;         /* the listener is read-only */
    unsigned refused;      /* writes refused by access control */
    char who[160];         /* peer, for the log */
    struct mb_map_query q; /* per-connection query state */
    uint8_t held[MODBUS_TCP_MAX_ADU_LENGTH];
    int held_len; /* > 0: reply waits for the commit */
    int held_exc; /* exception to send instead, or 0 */
    struct model *held_model;
    uint64_t held_batch;                    /* the WAL batch its reply waits for */
    uint8_t rsp[MODBUS_TCP_MAX_ADU_LENGTH]; /* the reply, framed */
    int rsp_len;
};

/* Attach ctx (no allocation). Returns 0. */
int mb_req_session_init(struct mb_req_session *s, modbus_t *ctx, int is_tcp);
void mb_req_session_free(struct mb_req_session *s);

/* Handle one complete ADU (header + PDU, and for RTU the checked CRC, as
 * modbus_reply expects). Returns 0
 * when answered (or ignored), 1 when held for the commit, -1 when the
 * connection should be closed (send failure). */
int mb_req_handle(struct mb_req_session *s, const uint8_t *req, int len, const struct mb_map_opts *o);

/* After store_commit(): answer a held request (commit_ok 0 turns it into
 * exception 04). Returns 0 or -1 on send failure. */
int mb_req_release(struct mb_req_session *s, int commit_ok);

#endif
