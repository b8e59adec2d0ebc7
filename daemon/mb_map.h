/* mb_map — serving the register map (regmap/it2n_regmap.h) for one model:
 * reads fill registers from the model and the connection's query; writes
 * are validated completely before anything changes. Returns Modbus
 * exception codes so the transports only frame. No I/O here. */
#ifndef IT2ND_MB_MAP_H
#define IT2ND_MB_MAP_H

#include <stdint.h>

#include "it2n.h"
#include "it2n_regmap.h"
#include "models.h"

/* Modbus exception codes used by the map. */
enum {
    MB_MAP_OK = 0,
    MB_MAP_ILLEGAL_FUNCTION = 0x01,
    MB_MAP_ILLEGAL_ADDRESS = 0x02,
    MB_MAP_ILLEGAL_VALUE = 0x03,
    MB_MAP_DEVICE_FAILURE = 0x04,
    MB_MAP_BUSY = 0x06,
    MB_MAP_GATEWAY_TARGET = 0x0B
};

struct mb_map_opts {
    int word_order;      /* enum it2n_regmap_order */
    int32_t coord_scale; /* coordinates: register = value * scale */
    unsigned grid_rows, grid_cols;
    /* Bit u set: unit u is write-protected ([model:] write_protect): no
     * Modbus write may change its model (query registers stay writable). */
    uint8_t write_protect[32];
    int int32_order; /* enum it2n_regmap_order of u32/i32 registers */
    /* Modbus TCP unit ids 0 and 255 ("this server", the Modbus TCP spec's
     * 0xFF) reach the model on this unit; 0 = they answer 0B. */
    int default_unit;
};

/* Does a write of count registers at addr change the model (configuration
 * or upload block), as opposed to the per-connection query registers? */
int mb_map_write_changes_model(unsigned addr, unsigned count);

/* The same for the block it2n_regmap_find(addr, count) returned (NULL: a
 * range outside the map, which changes nothing). */
int mb_map_block_changes_model(const it2n_regmap_block *b);

/* Per-connection query state. Zero-initialise. */
struct mb_map_query {
    uint16_t regs[IT2N_REGMAP_REG_QUERY_END - IT2N_REGMAP_REG_Q_U16]; /* inputs as written */
    int kind;                                                         /* 0 none, 1 (u, w), 2 (x, y) */
    it2n_par u, w;
    it2n_val x, y;
    /* The other views of the inputs (u as x10000 and float, likewise w,
     * x, y) still to be written into regs, when the query block is read
     * (a query's write need not format them): bit 0 (u, w), bit 1 (x, y),
     * in the word orders and scale of the write that made them due. */
    unsigned views_due;
    int uv_order, xy_order, xy_int32_order;
    int32_t xy_scale;
    /* (write_query copies the fields above, the inputs, up to `valid`.) */
    /* Cached result, valid when valid && the same model instance (not
     * just id: a model removed and added again by a reload) && gen. */
    int valid;
    uint32_t model_inst;
    uint32_t gen;
    it2n_point pt;
    uint16_t locfail;
    /* The coefficient page selected (footprint, channel, row). */
    uint16_t page[IT2N_REGMAP_REG_PAGE_END - IT2N_REGMAP_REG_PG_FP];
};

/* Read count registers from addr into out. Returns MB_MAP_OK or an exception
 * (02 outside the map, 06 results while unsolved, 04 evaluation failure). */
int mb_map_read(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, unsigned addr, unsigned count,
                uint16_t *out);

/* mb_map_read with b = it2n_regmap_find(addr, count) already looked up
 * (the request handler looks each range up once). */
int mb_map_read_in(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const it2n_regmap_block *b,
                   unsigned addr, unsigned count, uint16_t *out);

/* Write count registers. Validates fully first; on any exception nothing
 * changed but the model's last_error, which says why (an it2n code, or
 * the daemon's, errs.h). *persisted set to 1 when the model changed (the
 * reply must wait for the WAL commit). */
int mb_map_write(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, unsigned addr, unsigned count,
                 const uint16_t *vals, int *persisted);

/* mb_map_write with b = it2n_regmap_find(addr, count) already looked up. */
int mb_map_write_in(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, const it2n_regmap_block *b,
                    unsigned addr, unsigned count, const uint16_t *vals, int *persisted);

/* A write request refused before mb_map_write (malformed PDU: exception
 * exc): set the model's last_error accordingly. */
void mb_map_refused(struct model *md, int exc);

#endif
