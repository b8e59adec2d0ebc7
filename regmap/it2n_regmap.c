/*
 * it2n_regmap.c — the register map table. Pure data: docs/registers.md is
 * generated from it, so descriptions are written for a PLC engineer.
 */
#include "it2n_regmap.h"

/* clang-format off */
#define F1(a, t, s, n, u, d) { (a), 1u, 0u, (t), (s), (n), (u), (d) }
#define FN(a, c, st, t, s, n, u, d) { (a), (c), (st), (t), (s), (n), (u), (d) }
#define NF(x) (sizeof(x) / sizeof((x)[0]))

static const it2n_regmap_field status_fields[] = {
    F1(IT2N_REGMAP_REG_MAP_VERSION, IT2N_REGMAP_TYPE_U16, 1, "map_version", "-",
       "Register map layout version (1)."),
    F1(IT2N_REGMAP_REG_STATE, IT2N_REGMAP_TYPE_U16, 1, "state", "-",
       "0 empty, 1 incomplete (points missing), 2 solved, 3 solve failed."),
    F1(IT2N_REGMAP_REG_N, IT2N_REGMAP_TYPE_U16, 1, "n", "-", "Degree in u (grid rows - 1)."),
    F1(IT2N_REGMAP_REG_M, IT2N_REGMAP_TYPE_U16, 1, "m", "-", "Degree in w (grid columns - 1)."),
    F1(IT2N_REGMAP_REG_FLAGS, IT2N_REGMAP_TYPE_U16, 1, "flags", "bits",
       "bit0 z coordinates, bit1 type-1 (footprint D only), bit2 chord-length parameters."),
    F1(IT2N_REGMAP_REG_PRESENT, IT2N_REGMAP_TYPE_U16, 1, "points_present", "entries",
       "(i, j, footprint) entries received for the current configuration."),
    F1(IT2N_REGMAP_REG_REQUIRED, IT2N_REGMAP_TYPE_U16, 1, "points_required", "entries",
       "Entries a complete model needs: (n+1)(m+1) x footprints."),
    F1(IT2N_REGMAP_REG_GENERATION, IT2N_REGMAP_TYPE_U32, 1, "generation", "-",
       "Bumped on every solve or incremental update; poll it to see new results."),
    F1(IT2N_REGMAP_REG_LAST_ERR, IT2N_REGMAP_TYPE_I16, 1, "last_error", "-",
       "Last it2n error code (0 none, -1 invalid, -2 range, -5 order, -6 overflow, -7 singular, -8 degenerate)."),
    F1(IT2N_REGMAP_REG_ERR_I, IT2N_REGMAP_TYPE_I16, 1, "last_error_i", "-", "Grid row of the last error, or -1."),
    F1(IT2N_REGMAP_REG_ERR_J, IT2N_REGMAP_TYPE_I16, 1, "last_error_j", "-", "Grid column of the last error, or -1."),
    F1(IT2N_REGMAP_REG_ERR_FP, IT2N_REGMAP_TYPE_I16, 1, "last_error_fp", "-", "Footprint (0 LL .. 6 RR) of the last error, or -1."),
    F1(IT2N_REGMAP_REG_POINTS_RX, IT2N_REGMAP_TYPE_U32, 1, "points_received", "count",
       "Data points accepted since start (links and Modbus)."),
    F1(IT2N_REGMAP_REG_SOLVES, IT2N_REGMAP_TYPE_U32, 1, "solves", "count", "Successful full solves since start."),
    F1(IT2N_REGMAP_REG_REQUESTS, IT2N_REGMAP_TYPE_U32, 1, "requests", "count", "Modbus requests served for this unit."),
    F1(IT2N_REGMAP_REG_EXCEPTIONS, IT2N_REGMAP_TYPE_U32, 1, "exceptions", "count", "Modbus exception replies for this unit."),
    F1(IT2N_REGMAP_REG_WORD_ORDER, IT2N_REGMAP_TYPE_U16, 1, "float_word_order", "-",
       "Float32 byte order: 0 ABCD (big-endian, default), 1 CDAB, 2 BADC, 3 DCBA."),
    F1(IT2N_REGMAP_REG_COORD_SCALE, IT2N_REGMAP_TYPE_U16, 1, "coord_scale", "-",
       "Coordinate scale of scaled-integer coordinates: value = register / coord_scale."),
    F1(IT2N_REGMAP_REG_GRID_ROWS, IT2N_REGMAP_TYPE_U16, 1, "grid_rows", "-", "Rows of the sample grid block."),
    F1(IT2N_REGMAP_REG_GRID_COLS, IT2N_REGMAP_TYPE_U16, 1, "grid_cols", "-", "Columns of the sample grid block."),
    F1(IT2N_REGMAP_REG_MODEL_ID, IT2N_REGMAP_TYPE_U16, 1, "model_id", "-", "Model id on the serial links."),
    F1(IT2N_REGMAP_REG_GRID_SAT, IT2N_REGMAP_TYPE_U16, 1, "grid_saturated", "count",
       "Sample-grid values outside +-3.2767 that the x10000 sample_grid view clamps to +-32767 "
       "(interpolants may overshoot between data points); 0 when none or not solved. "
       "sample_grid_f32 has the raw values."),
    F1(IT2N_REGMAP_REG_INT32_ORDER, IT2N_REGMAP_TYPE_U16, 1, "int32_word_order", "-",
       "Word and byte order of every u32/i32 register, coded as float_word_order "
       "([modbus] int32_word_order; by default the same as float_word_order, so a PLC sees one order)."),
    F1(IT2N_REGMAP_REG_KIND, IT2N_REGMAP_TYPE_U16, 1, "kind", "-",
       "Model kind ([model:ID] kind): 0 Bezier (n, m are degrees 1..7), 1 B-spline (cubic, not-a-knot; "
       "n, m are intervals 1..255, a grid of (n+1) x (m+1) points)."),
    F1(IT2N_REGMAP_REG_NET_ROWS, IT2N_REGMAP_TYPE_U16, 1, "net_rows", "-",
       "Rows of each solved coefficient net: n+1 control points (Bezier), n+3 B-spline coefficients; "
       "0 while not solved. Read them page by page (coef_page, coef_window)."),
    F1(IT2N_REGMAP_REG_NET_COLS, IT2N_REGMAP_TYPE_U16, 1, "net_cols", "-",
       "Columns of each solved coefficient net: m+1 (Bezier), m+3 (B-spline); 0 while not solved."),
    F1(IT2N_REGMAP_REG_STATUS_RSV, IT2N_REGMAP_TYPE_U16, 1, "reserved", "-", "Reads 0."),
};

static const it2n_regmap_field counts_fields[] = {
    F1(IT2N_REGMAP_REG_PRESENT32, IT2N_REGMAP_TYPE_U32, 1, "points_present32", "entries",
       "points_present as u32 (registers 5 and 6 stop at 65535; a 256 x 256 type-2 grid needs 458752)."),
    F1(IT2N_REGMAP_REG_REQUIRED32, IT2N_REGMAP_TYPE_U32, 1, "points_required32", "entries", "points_required as u32."),
};

static const it2n_regmap_field page_fields[] = {
    F1(IT2N_REGMAP_REG_PG_FP, IT2N_REGMAP_TYPE_U16, 1, "coef_fp", "-", "Footprint of the coefficient page, 0 LL .. 6 RR."),
    F1(IT2N_REGMAP_REG_PG_CH, IT2N_REGMAP_TYPE_U16, 1, "coef_ch", "-", "Channel of the page: 0 x, 1 y, 2 z, 3 T, 4 I, 5 F."),
    F1(IT2N_REGMAP_REG_PG_ROW, IT2N_REGMAP_TYPE_U16, 1, "coef_row", "-",
       "Row r of the net, 0..net_rows-1 (at most 257). Values above the limits answer 03."),
};

static const it2n_regmap_field win_fields[] = {
    FN(IT2N_REGMAP_REG_WIN, IT2N_REGMAP_WIN_COLS, 2u, IT2N_REGMAP_TYPE_F32, 1, "coef[s]", "coord / 1",
       "Coefficient (coef_row, s) of net (coef_fp, coef_ch) at 384 + s*2, s = 0..net_cols-1: a Bezier "
       "control point, or the B-spline coefficient c(r-1, s-1) (the surface is sum c(k,l) N_k(u) N_l(w) "
       "over the cubic B-splines of the uniform knots, docs/numerics.md). Columns past net_cols, rows past "
       "net_rows and footprints the model does not carry read 0."),
};

static const it2n_regmap_field config_fields[] = {
    F1(IT2N_REGMAP_REG_CFG_N, IT2N_REGMAP_TYPE_U16, 1, "cfg_n", "-",
       "Degree in u, 1..7 (B-spline kind: intervals, 1 up to the n of its [model:ID] section). "
       "Writing a new configuration clears the model's points."),
    F1(IT2N_REGMAP_REG_CFG_M, IT2N_REGMAP_TYPE_U16, 1, "cfg_m", "-", "Degree in w, 1..7 (B-spline: intervals, up to the configured m)."),
    F1(IT2N_REGMAP_REG_CFG_FLAGS, IT2N_REGMAP_TYPE_U16, 1, "cfg_flags", "bits",
       "bit0 z, bit1 type-1, bit2 chord-length (Bezier only); other bits answer 03."),
    F1(IT2N_REGMAP_REG_COMMAND, IT2N_REGMAP_TYPE_U16, 1, "command", "-",
       "Write 1 = commit (solve now; 06 while points are missing, 04 if the solve fails), 2 = clear points. Reads 0."),
};

static const it2n_regmap_field upload_fields[] = {
    F1(IT2N_REGMAP_REG_UP_I, IT2N_REGMAP_TYPE_U16, 1, "up_i", "-", "Grid row 0..n (up to 255 for the B-spline kind)."),
    F1(IT2N_REGMAP_REG_UP_J, IT2N_REGMAP_TYPE_U16, 1, "up_j", "-", "Grid column 0..m."),
    F1(IT2N_REGMAP_REG_UP_FP, IT2N_REGMAP_TYPE_U16, 1, "up_fp", "-", "Footprint 0 LL, 1 LR, 2 L, 3 D, 4 R, 5 RL, 6 RR."),
    F1(IT2N_REGMAP_REG_UP_X, IT2N_REGMAP_TYPE_I32, IT2N_REGMAP_SCALE_COORD, "up_x", "coord", "x coordinate."),
    F1(IT2N_REGMAP_REG_UP_Y, IT2N_REGMAP_TYPE_I32, IT2N_REGMAP_SCALE_COORD, "up_y", "coord", "y coordinate."),
    F1(IT2N_REGMAP_REG_UP_Z, IT2N_REGMAP_TYPE_I32, IT2N_REGMAP_SCALE_COORD, "up_z", "coord", "z coordinate (ignored without flag z)."),
    F1(IT2N_REGMAP_REG_UP_T, IT2N_REGMAP_TYPE_U16, IT2N_REGMAP_MEMB_SCALE, "up_T", "1", "Truth membership, 0..10000."),
    F1(IT2N_REGMAP_REG_UP_I_M, IT2N_REGMAP_TYPE_U16, IT2N_REGMAP_MEMB_SCALE, "up_I", "1", "Indeterminacy membership, 0..10000."),
    F1(IT2N_REGMAP_REG_UP_F, IT2N_REGMAP_TYPE_U16, IT2N_REGMAP_MEMB_SCALE, "up_F", "1", "Falsity membership, 0..10000."),
};

static const it2n_regmap_field query_fields[] = {
    F1(IT2N_REGMAP_REG_Q_U16, IT2N_REGMAP_TYPE_U16, IT2N_REGMAP_MEMB_SCALE, "q_u", "1", "Parameter u x10000 (0..10000)."),
    F1(IT2N_REGMAP_REG_Q_W16, IT2N_REGMAP_TYPE_U16, IT2N_REGMAP_MEMB_SCALE, "q_w", "1", "Parameter w x10000 (0..10000)."),
    F1(IT2N_REGMAP_REG_Q_UF, IT2N_REGMAP_TYPE_F32, 1, "q_u_f", "1", "Parameter u as float32, [0, 1]."),
    F1(IT2N_REGMAP_REG_Q_WF, IT2N_REGMAP_TYPE_F32, 1, "q_w_f", "1", "Parameter w as float32, [0, 1]."),
    F1(IT2N_REGMAP_REG_Q_XS, IT2N_REGMAP_TYPE_I32, IT2N_REGMAP_SCALE_COORD, "q_x", "coord", "Locate: x, scaled integer."),
    F1(IT2N_REGMAP_REG_Q_YS, IT2N_REGMAP_TYPE_I32, IT2N_REGMAP_SCALE_COORD, "q_y", "coord", "Locate: y, scaled integer."),
    F1(IT2N_REGMAP_REG_Q_XF, IT2N_REGMAP_TYPE_F32, 1, "q_x_f", "coord", "Locate: x as float32."),
    F1(IT2N_REGMAP_REG_Q_YF, IT2N_REGMAP_TYPE_F32, 1, "q_y_f", "coord", "Locate: y as float32."),
};

static const it2n_regmap_field qstatus_fields[] = {
    F1(IT2N_REGMAP_REG_Q_KIND, IT2N_REGMAP_TYPE_U16, 1, "q_kind", "-", "0 no query yet, 1 (u, w) evaluation, 2 (x, y) locate."),
    F1(IT2N_REGMAP_REG_Q_GEN, IT2N_REGMAP_TYPE_U32, 1, "q_generation", "-", "Model generation the results were computed from."),
    F1(IT2N_REGMAP_REG_Q_LOCFAIL, IT2N_REGMAP_TYPE_U16, 1, "q_locate_fail", "bits",
       "Locate only: bit fp set when (x, y) is not inside that footprint surface (nearest boundary point given)."),
    F1(IT2N_REGMAP_REG_Q_OOR, IT2N_REGMAP_TYPE_U32, 1, "q_out_of_range", "bits",
       "Bit fp*3+k: membership k (0 T, 1 I, 2 F) of footprint fp left [0, 1] (raw value kept)."),
};

static const it2n_regmap_field res_f32_fields[] = {
    FN(IT2N_REGMAP_REG_RES_F32, IT2N_REGMAP_FP * IT2N_REGMAP_CH, 2u, IT2N_REGMAP_TYPE_F32, 1, "res[fp][ch]", "coord / 1",
       "Surface value of footprint fp (0 LL..6 RR), channel ch (0 x, 1 y, 2 z, 3 T, 4 I, 5 F) at "
       "address 128 + (fp*6 + ch)*2."),
    FN(IT2N_REGMAP_REG_SUM_F32, 12u, 2u, IT2N_REGMAP_TYPE_F32, 1, "sum[s][k]", "1",
       "Interval summary: s = 0 upper_min, 1 upper_max (over LL, D, RR), 2 lower_min, 3 lower_max "
       "(over LR, D, RL); k = 0 T, 1 I, 2 F; address 212 + (s*3 + k)*2."),
};

static const it2n_regmap_field res_sc_fields[] = {
    FN(IT2N_REGMAP_REG_RES_SCALED, IT2N_REGMAP_FP, IT2N_REGMAP_REG_RES_SCALED_STRIDE, IT2N_REGMAP_TYPE_I32,
       IT2N_REGMAP_SCALE_COORD, "res_xyz[fp]", "coord",
       "x, y, z of footprint fp as three i32 at 256 + fp*9 + {0, 2, 4}, saturated to the i32 range."),
    FN(IT2N_REGMAP_REG_RES_SCALED + 6u, IT2N_REGMAP_FP, IT2N_REGMAP_REG_RES_SCALED_STRIDE, IT2N_REGMAP_TYPE_I16,
       IT2N_REGMAP_MEMB_SCALE, "res_tif[fp]", "1",
       "T, I, F of footprint fp as three i16 x10000 at 256 + fp*9 + {6, 7, 8}, saturated to +-32767."),
    FN(IT2N_REGMAP_REG_SUM_SCALED, 12u, 1u, IT2N_REGMAP_TYPE_I16, IT2N_REGMAP_MEMB_SCALE, "sum_sc[s][k]", "1",
       "Interval summary as i16 x10000 at 320 + s*3 + k (s, k as in the float32 summary)."),
    FN(IT2N_REGMAP_REG_SAT, IT2N_REGMAP_FP, 1u, IT2N_REGMAP_TYPE_U16, 1, "sat[fp]", "bits",
       "Bit ch set when the scaled value of footprint fp, channel ch was saturated."),
    F1(IT2N_REGMAP_REG_SAT_SUM, IT2N_REGMAP_TYPE_U16, 1, "sat_sum", "bits",
       "Bit s*3+k set when scaled summary value (s, k) was saturated."),
};

static const it2n_regmap_field grid_fields[] = {
    FN(IT2N_REGMAP_REG_GRID, IT2N_REGMAP_GRID_MAX_NODES, 3u, IT2N_REGMAP_TYPE_I16, IT2N_REGMAP_MEMB_SCALE, "grid[r][c]", "1",
       "T, I, F of footprint D at u = r/(rows-1), w = c/(cols-1) as i16 x10000 at "
       "1024 + (r*cols + c)*3 + k. Only rows*cols nodes exist; reading past them answers 02."),
};

static const it2n_regmap_field grid_f32_fields[] = {
    FN(IT2N_REGMAP_REG_GRID_F32, IT2N_REGMAP_GRID_MAX_NODES * 3u, 2u, IT2N_REGMAP_TYPE_F32, 1, "grid_f[r][c]", "1",
       "T, I, F of footprint D at node (r, c) as float32 at 8192 + ((r*cols + c)*3 + k)*2. Only rows*cols "
       "nodes exist; reading past them answers 02."),
};

static const it2n_regmap_field ctrl_fields[] = {
    FN(IT2N_REGMAP_REG_CTRL, IT2N_REGMAP_FP * IT2N_REGMAP_DIM * IT2N_REGMAP_DIM * IT2N_REGMAP_CH, 2u,
       IT2N_REGMAP_TYPE_F32, 1, "ctrl[fp][i][j][ch]", "coord / 1",
       "Control point (i, j) of footprint fp, channel ch at 2048 + (((fp*8 + i)*8 + j)*6 + ch)*2; "
       "entries outside the model's degrees read 0."),
};

const it2n_regmap_block it2n_regmap_blocks[] = {
    { IT2N_REGMAP_REG_MAP_VERSION, IT2N_REGMAP_REG_STATUS_END, IT2N_REGMAP_ACCESS_RO, 0u, "status",
      "Model state and counters.", status_fields, NF(status_fields) },
    { IT2N_REGMAP_REG_CFG_N, IT2N_REGMAP_REG_CONFIG_END, IT2N_REGMAP_ACCESS_RW, 0u, "configuration",
      "Model configuration and command. Writes are persisted before the reply.",
      config_fields, NF(config_fields) },
    { IT2N_REGMAP_REG_UP_I, IT2N_REGMAP_REG_UPLOAD_END, IT2N_REGMAP_ACCESS_RW, 0u, "upload",
      "One data point, written as the whole block (40..51, 12 registers) in one FC16/FC23 request; "
      "any other write here answers 03. Stored (and persisted) before the reply; completes or "
      "updates the model like a point from a link.", upload_fields, NF(upload_fields) },
    { IT2N_REGMAP_REG_Q_U16, IT2N_REGMAP_REG_QUERY_END, IT2N_REGMAP_ACCESS_RW, 1u, "query",
      "Per-connection query inputs. Writing u and/or w (either view) evaluates at (u, w); writing x "
      "and/or y locates (x, y) on every footprint. Both views of an input then read the value in use "
      "(after q_u_f = 0.123456, q_u reads 1235). 32-bit values must be written whole; one write may "
      "not mix (u, w) with (x, y). Use FC23 to write and read the result in one transaction.",
      query_fields, NF(query_fields) },
    { IT2N_REGMAP_REG_Q_KIND, IT2N_REGMAP_REG_QSTATUS_END, IT2N_REGMAP_ACCESS_RO, 1u, "query_status",
      "Per-connection query status.", qstatus_fields, NF(qstatus_fields) },
    { IT2N_REGMAP_REG_PRESENT32, IT2N_REGMAP_REG_COUNTS_END, IT2N_REGMAP_ACCESS_RO, 0u, "counts",
      "Entry counts of the current configuration as u32.", counts_fields, NF(counts_fields) },
    { IT2N_REGMAP_REG_PG_FP, IT2N_REGMAP_REG_PAGE_END, IT2N_REGMAP_ACCESS_RW, 1u, "coef_page",
      "Per-connection page select of the coefficient window: one row of one net (footprint, channel). "
      "Selecting a page changes no model (allowed on write-protected units and read-only listeners). "
      "Nets of any size, both kinds: status registers 28..30 give the kind and the net's rows and columns.",
      page_fields, NF(page_fields) },
    { IT2N_REGMAP_REG_RES_F32, IT2N_REGMAP_REG_SUM_F32 + 24u, IT2N_REGMAP_ACCESS_RO, 1u, "results_f32",
      "Result of this connection's last query, float32 view (recomputed when the model changes). "
      "Answers 06 while the model is not solved.", res_f32_fields, NF(res_f32_fields) },
    { IT2N_REGMAP_REG_RES_SCALED, IT2N_REGMAP_REG_RESULTS_END, IT2N_REGMAP_ACCESS_RO, 1u, "results_scaled",
      "Result of this connection's last query, scaled-integer view with saturation flags. "
      "Answers 06 while the model is not solved.", res_sc_fields, NF(res_sc_fields) },
    { IT2N_REGMAP_REG_WIN, IT2N_REGMAP_REG_WIN_END, IT2N_REGMAP_ACCESS_RO, 1u, "coef_window",
      "The row coef_page selects, float32 (configured word order), read in as many requests as a PLC "
      "needs (125 registers each at most): a 256 x 256 B-spline net row is 258 values. Answers 06 while "
      "the model is not solved.", win_fields, NF(win_fields) },
    { IT2N_REGMAP_REG_GRID, IT2N_REGMAP_REG_GRID_END, IT2N_REGMAP_ACCESS_RO, 0u, "sample_grid",
      "Precomputed sample grid (grid_rows x grid_cols, configured), refreshed on every generation. "
      "Answers 06 while the model is not solved.", grid_fields, NF(grid_fields) },
    { IT2N_REGMAP_REG_CTRL, IT2N_REGMAP_REG_CTRL_END, IT2N_REGMAP_ACCESS_RO, 0u, "control_net",
      "Solved control nets, float32 only: control points of memberships are not bounded to [0, 1], so a "
      "x10000 integer view would saturate. Answers 06 while the model is not solved. Bezier kind only "
      "(a B-spline model answers 02 here: read its coefficients through coef_window).",
      ctrl_fields, NF(ctrl_fields) },
    { IT2N_REGMAP_REG_GRID_F32, IT2N_REGMAP_REG_GRID_F32_END, IT2N_REGMAP_ACCESS_RO, 0u, "sample_grid_f32",
      "The sample grid again, float32 view (same nodes and refresh as sample_grid). "
      "Answers 06 while the model is not solved.", grid_f32_fields, NF(grid_f32_fields) },
};
/* clang-format on */

const size_t it2n_regmap_nblocks = NF(it2n_regmap_blocks);

const it2n_regmap_block *it2n_regmap_find(unsigned addr, unsigned count)
{
    /* The table is in address order (tests/regmap checks it): the first
     * block ending above addr is the only one that can hold it (one
     * compare per block passed: it2nd looks up every request's range, the
     * FC 23 query's blocks are the 4th and 8th). */
    const it2n_regmap_block *b = it2n_regmap_blocks, *end = b + it2n_regmap_nblocks;
    if (count == 0u)
        return NULL;
    while (b < end && addr >= b->end)
        b++;
    if (b == end || addr < b->start)
        return NULL;
    return (count <= (unsigned)(b->end - addr)) ? b : NULL;
}

const char *it2n_regmap_type_name(unsigned type)
{
    static const char *const names[] = {"u16", "i16", "u32", "i32", "f32"};
    return type < 5u ? names[type] : "?";
}

unsigned it2n_regmap_type_words(unsigned type)
{
    return (type == IT2N_REGMAP_TYPE_U16 || type == IT2N_REGMAP_TYPE_I16) ? 1u : 2u;
}
