/*
 * it2n_regmap — the it2nd Modbus register map, defined once as data, and
 * the codecs of the values it carries.
 *
 * Every address the daemon serves is listed in it2n_regmap_blocks[]; the
 * daemon decodes requests against it, it2nctl and the PLC simulator read
 * it, and regmap/tools/gen_registers prints docs/registers.md from it.
 * Addresses are 0-based protocol (PDU) addresses; the documentation adds
 * the 3xxxx / 4xxxx reference notation.
 *
 * The codecs (32-bit word orders, float32, scaled integers, parameters
 * x10000) are the only copies in the tree: the daemon encodes with them,
 * the clients decode with them.
 *
 * Portable C99: data, lookups and pure functions; no heap, no state, no
 * I/O, no transport (the map knows registers, not Modbus frames), no
 * dependency beyond <stdint.h>, <stddef.h> and <string.h>.
 */
#ifndef IT2N_REGMAP_H
#define IT2N_REGMAP_H

#include <stddef.h>
#include <stdint.h>

/* Map layout version, readable at IT2N_REGMAP_REG_MAP_VERSION. Bump on any change
 * that moves or retypes a register. */
#define IT2N_REGMAP_VERSION 1u

/* Stride of the control-net read-out in i and j, independent of the core's
 * compile-time IT2N_MAX_DEGREE so addresses never move. */
#define IT2N_REGMAP_DIM 8u
#define IT2N_REGMAP_FP 7u /* footprints LL..RR */
#define IT2N_REGMAP_CH 6u /* channels x, y, z, T, I, F */
#define IT2N_REGMAP_GRID_MAX_NODES 256u

/* Membership scale of every scaled-integer membership register. */
#define IT2N_REGMAP_MEMB_SCALE 10000

/* ---- Status (read-only) ---- */
#define IT2N_REGMAP_REG_MAP_VERSION 0u
#define IT2N_REGMAP_REG_STATE 1u /* enum it2n_regmap_state            */
#define IT2N_REGMAP_REG_N 2u
#define IT2N_REGMAP_REG_M 3u
#define IT2N_REGMAP_REG_FLAGS 4u
#define IT2N_REGMAP_REG_PRESENT 5u    /* (i, j, footprint) entries present */
#define IT2N_REGMAP_REG_REQUIRED 6u   /* entries a complete model needs    */
#define IT2N_REGMAP_REG_GENERATION 7u /* u32, bumped on every solve/update */
#define IT2N_REGMAP_REG_LAST_ERR 9u   /* i16 it2n error code, 0 = none     */
#define IT2N_REGMAP_REG_ERR_I 10u
#define IT2N_REGMAP_REG_ERR_J 11u
#define IT2N_REGMAP_REG_ERR_FP 12u
#define IT2N_REGMAP_REG_POINTS_RX 13u  /* u32 */
#define IT2N_REGMAP_REG_SOLVES 15u     /* u32 */
#define IT2N_REGMAP_REG_REQUESTS 17u   /* u32 */
#define IT2N_REGMAP_REG_EXCEPTIONS 19u /* u32 */
#define IT2N_REGMAP_REG_WORD_ORDER 21u
#define IT2N_REGMAP_REG_COORD_SCALE 22u
#define IT2N_REGMAP_REG_GRID_ROWS 23u
#define IT2N_REGMAP_REG_GRID_COLS 24u
#define IT2N_REGMAP_REG_MODEL_ID 25u
#define IT2N_REGMAP_REG_GRID_SAT 26u    /* grid values the x10000 view clamps */
#define IT2N_REGMAP_REG_INT32_ORDER 27u /* word order of u32/i32 registers */
#define IT2N_REGMAP_REG_KIND 28u        /* enum it2n_regmap_kind */
#define IT2N_REGMAP_REG_NET_ROWS 29u    /* coefficient rows of the solved net, 0 unsolved */
#define IT2N_REGMAP_REG_NET_COLS 30u    /* coefficient columns */
#define IT2N_REGMAP_REG_STATUS_RSV 31u  /* reads 0 */
#define IT2N_REGMAP_REG_STATUS_END 32u

/* ---- Model configuration (read/write) ---- */
#define IT2N_REGMAP_REG_CFG_N 32u
#define IT2N_REGMAP_REG_CFG_M 33u
#define IT2N_REGMAP_REG_CFG_FLAGS 34u
#define IT2N_REGMAP_REG_COMMAND 35u
#define IT2N_REGMAP_REG_CONFIG_END 36u

/* ---- Data point upload (read/write, whole block in one request) ---- */
#define IT2N_REGMAP_REG_UP_I 40u
#define IT2N_REGMAP_REG_UP_J 41u
#define IT2N_REGMAP_REG_UP_FP 42u
#define IT2N_REGMAP_REG_UP_X 43u /* i32 scaled by the coordinate scale */
#define IT2N_REGMAP_REG_UP_Y 45u
#define IT2N_REGMAP_REG_UP_Z 47u
#define IT2N_REGMAP_REG_UP_T 49u /* u16 x10000 */
#define IT2N_REGMAP_REG_UP_I_M 50u
#define IT2N_REGMAP_REG_UP_F 51u
#define IT2N_REGMAP_REG_UPLOAD_END 52u

/* ---- Query inputs (read/write, per connection) ---- */
#define IT2N_REGMAP_REG_Q_U16 64u /* u x10000 */
#define IT2N_REGMAP_REG_Q_W16 65u /* w x10000 */
#define IT2N_REGMAP_REG_Q_UF 66u  /* f32 */
#define IT2N_REGMAP_REG_Q_WF 68u  /* f32 */
#define IT2N_REGMAP_REG_Q_XS 70u  /* i32 scaled */
#define IT2N_REGMAP_REG_Q_YS 72u  /* i32 scaled */
#define IT2N_REGMAP_REG_Q_XF 74u  /* f32 */
#define IT2N_REGMAP_REG_Q_YF 76u  /* f32 */
#define IT2N_REGMAP_REG_QUERY_END 78u

/* ---- Point counts as u32 (read-only): a B-spline grid may need more
 * than the u16 status registers 5 and 6 hold ---- */
#define IT2N_REGMAP_REG_PRESENT32 88u
#define IT2N_REGMAP_REG_REQUIRED32 90u
#define IT2N_REGMAP_REG_COUNTS_END 92u

/* ---- Coefficient page select (read/write, per connection) ---- */
#define IT2N_REGMAP_REG_PG_FP 96u
#define IT2N_REGMAP_REG_PG_CH 97u
#define IT2N_REGMAP_REG_PG_ROW 98u
#define IT2N_REGMAP_REG_PAGE_END 99u

/* ---- Query status (read-only, per connection) ---- */
#define IT2N_REGMAP_REG_Q_KIND 80u    /* 0 none, 1 (u, w), 2 (x, y)        */
#define IT2N_REGMAP_REG_Q_GEN 81u     /* u32 model generation of the result */
#define IT2N_REGMAP_REG_Q_LOCFAIL 83u /* bit fp: (x, y) not inside surface  */
#define IT2N_REGMAP_REG_Q_OOR 84u     /* u32, bit fp*3+k: membership k outside [0,1] */
#define IT2N_REGMAP_REG_QSTATUS_END 86u

/* ---- Results ---- */
#define IT2N_REGMAP_REG_RES_F32 128u    /* f32 v[fp][ch], 2 words each   */
#define IT2N_REGMAP_REG_SUM_F32 212u    /* f32 summary, 12 values        */
#define IT2N_REGMAP_REG_RES_SCALED 256u /* per fp: x,y,z i32; T,I,F i16  */
#define IT2N_REGMAP_REG_RES_SCALED_STRIDE 9u
#define IT2N_REGMAP_REG_SUM_SCALED 320u /* i16 x10000, 12 values         */
#define IT2N_REGMAP_REG_SAT 332u        /* per fp saturation mask, bit ch */
#define IT2N_REGMAP_REG_SAT_SUM 339u    /* summary saturation mask, bit k */
#define IT2N_REGMAP_REG_RESULTS_END 340u

/* ---- Coefficient window (read-only, per connection): f32 coefficients
 * of the selected row, up to IT2N_REGMAP_WIN_COLS ---- */
#define IT2N_REGMAP_WIN_COLS 258u /* a 256 x 256 B-spline net has 258 columns */
#define IT2N_REGMAP_WIN_ROWS 258u
#define IT2N_REGMAP_REG_WIN 384u
#define IT2N_REGMAP_REG_WIN_END (IT2N_REGMAP_REG_WIN + 2u * IT2N_REGMAP_WIN_COLS)

/* ---- Sample grid (read-only): D footprint T, I, F x10000 per node ---- */
#define IT2N_REGMAP_REG_GRID 1024u
#define IT2N_REGMAP_REG_GRID_END (IT2N_REGMAP_REG_GRID + 3u * IT2N_REGMAP_GRID_MAX_NODES)

/* ---- Control nets (read-only): f32 ctrl[fp][i][j][ch] ---- */
#define IT2N_REGMAP_REG_CTRL 2048u
#define IT2N_REGMAP_REG_CTRL_END \
    (IT2N_REGMAP_REG_CTRL + 2u * IT2N_REGMAP_FP * IT2N_REGMAP_DIM * IT2N_REGMAP_DIM * IT2N_REGMAP_CH)

/* ---- Sample grid, float32 view: D footprint T, I, F per node ---- */
#define IT2N_REGMAP_REG_GRID_F32 8192u
#define IT2N_REGMAP_REG_GRID_F32_END (IT2N_REGMAP_REG_GRID_F32 + 6u * IT2N_REGMAP_GRID_MAX_NODES)

/* One past the highest address of the map. */
#define IT2N_REGMAP_REG_MAP_END IT2N_REGMAP_REG_GRID_F32_END

/* Values of IT2N_REGMAP_REG_KIND. */
enum it2n_regmap_kind {
    IT2N_REGMAP_KIND_BEZIER = 0, /* one Bezier patch, degrees 1..7 */
    IT2N_REGMAP_KIND_BSPLINE = 1 /* cubic B-spline, not-a-knot, 1..255 intervals */
};

/* Values of IT2N_REGMAP_REG_STATE. */
enum it2n_regmap_state {
    IT2N_REGMAP_STATE_EMPTY = 0,      /* no data point yet                       */
    IT2N_REGMAP_STATE_INCOMPLETE = 1, /* points missing; results answer 06       */
    IT2N_REGMAP_STATE_SOLVED = 2,     /* results valid                           */
    IT2N_REGMAP_STATE_FAILED = 3      /* complete but the solve failed (LAST_ERR) */
};

/* Values written to IT2N_REGMAP_REG_COMMAND. */
enum it2n_regmap_cmd {
    IT2N_REGMAP_CMD_COMMIT = 1, /* solve now (fails 06 while points are missing) */
    IT2N_REGMAP_CMD_CLEAR = 2   /* drop all points, keep the configuration       */
};

/* Word orders for float32 (IT2N_REGMAP_REG_WORD_ORDER); A is the most significant
 * byte of the IEEE-754 value. */
enum it2n_regmap_order {
    IT2N_REGMAP_WO_ABCD = 0,
    IT2N_REGMAP_WO_CDAB = 1,
    IT2N_REGMAP_WO_BADC = 2,
    IT2N_REGMAP_WO_DCBA = 3
};

/* Register value types. */
enum it2n_regmap_type {
    IT2N_REGMAP_TYPE_U16 = 0,
    IT2N_REGMAP_TYPE_I16,
    IT2N_REGMAP_TYPE_U32, /* two registers, int32_word_order (default: as float) */
    IT2N_REGMAP_TYPE_I32, /* two registers, int32_word_order (default: as float) */
    IT2N_REGMAP_TYPE_F32  /* two registers, configured word order */
};

/* Scale of a field: 1 plain, IT2N_REGMAP_SCALE_COORD the configured
 * coordinate scale, otherwise value = register / scale. */
#define IT2N_REGMAP_SCALE_COORD (-1)

/* Access. */
enum it2n_regmap_access { IT2N_REGMAP_ACCESS_RO = 0, IT2N_REGMAP_ACCESS_RW = 1 };

/* One field: `count` values of `type` starting at addr, `stride` registers
 * apart (count 1: stride unused). */
typedef struct it2n_regmap_field {
    uint16_t addr;
    uint16_t count;
    uint16_t stride;
    uint8_t type;  /* enum it2n_regmap_type */
    int32_t scale; /* 1, IT2N_REGMAP_SCALE_COORD or a divisor */
    const char *name;
    const char *unit;
    const char *desc;
} it2n_regmap_field;

/* One contiguous block of registers. Reads inside a block are valid
 * (subject to per-block rules in desc); reads outside every block answer
 * exception 02. */
typedef struct it2n_regmap_block {
    uint16_t start;
    uint16_t end;     /* one past the last register */
    uint8_t access;   /* enum it2n_regmap_access */
    uint8_t per_conn; /* 1: values belong to the Modbus connection */
    const char *name;
    const char *desc;
    const it2n_regmap_field *fields;
    size_t nfields;
} it2n_regmap_block;

extern const it2n_regmap_block it2n_regmap_blocks[];
extern const size_t it2n_regmap_nblocks;

/*
 * The block that wholly contains [addr, addr + count), or NULL if the range
 * leaves the map or spans two blocks. count must be >= 1.
 */
const it2n_regmap_block *it2n_regmap_find(unsigned addr, unsigned count);

/* Name of a type ("u16", ...), or "?". */
const char *it2n_regmap_type_name(unsigned type);

/* Registers one value of `type` occupies (1 or 2). */
unsigned it2n_regmap_type_words(unsigned type);

/* ---- Codecs ----
 * Fixed point as the it2n core carries it: values (coordinates,
 * memberships) are Q24 in an int64_t (1.0 = 2^24), parameters u, w are
 * Q32 (1.0 = 2^32). The map does not include the core: these are the
 * formats, the daemon checks they match the core's at compile time. */
#define IT2N_REGMAP_Q24_FRAC 24u
#define IT2N_REGMAP_PAR_FRAC 32u

/* 32 bits into two registers in word order `order` (enum
 * it2n_regmap_order: A is the most significant byte, ABCD puts AB in the
 * first register). Any other order is taken as ABCD. */
void it2n_regmap_put_u32(uint16_t out[2], uint32_t v, unsigned order);

/* The 32 bits two registers carry in word order `order` (as put_u32). */
uint32_t it2n_regmap_get_u32(const uint16_t in[2], unsigned order);

/* An IEEE-754 float32 into two registers in word order `order`. */
void it2n_regmap_put_f32(uint16_t out[2], float f, unsigned order);

/* The float32 two registers carry in word order `order`. */
float it2n_regmap_get_f32(const uint16_t in[2], unsigned order);

/* A Q24 value as float32: v / 2^24 rounded to nearest (exact for |v| up
 * to 2^24 units, i.e. 24 significant bits). */
float it2n_regmap_q24_to_f32(int64_t v);

/* n Q24 values as float32 into 2n registers (the result, grid and
 * coefficient blocks): the word order is chosen once per call, not per
 * value. */
void it2n_regmap_put_q24_f32s(uint16_t *out, const int64_t *v, size_t n, unsigned order);

/* A Q24 value as a scaled integer register value: v * scale / 2^24
 * rounded half away from zero, clamped to [lo, hi] (lo <= 0 <= hi). On a
 * clamp *sat is set to 1; otherwise it is left as it was, so one flag can
 * collect a whole block. scale >= 1. */
int64_t it2n_regmap_q24_to_scaled(int64_t v, int32_t scale, int64_t lo, int64_t hi, int *sat);

/* A scaled integer register value back to Q24: raw * 2^24 / scale
 * rounded half away from zero (the inverse the daemon applies to writes).
 * scale >= 1; results beyond +-2^62 saturate there. */
int64_t it2n_regmap_q24_from_scaled(int64_t raw, int32_t scale);

/* A parameter u or w (Q32, 0..2^32) as the x10000 register value
 * (rounded half up; values outside [0, 1] clamp to 0 or 10000). */
uint16_t it2n_regmap_par_to_u16(int64_t par);

/* An x10000 register value as a parameter (Q32, rounded half up); values
 * above 10000 give more than 1.0: the caller refuses them first. */
int64_t it2n_regmap_par_from_u16(unsigned reg);

#endif /* IT2N_REGMAP_H */
