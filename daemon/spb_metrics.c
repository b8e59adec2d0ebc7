/* spb_metrics.c — see spb_metrics.h. */
#include "spb_metrics.h"

#include <stdio.h>
#include <string.h>

/* The metric list of a device, in this order (index K, alias
 * (N + 1) * SPB_DEV_ALIAS + K):
 *   Status/<name>         every field of the status block (registers 0..27)
 *   Query/u, Query/w      the device's query (Float; written by DCMD)
 *   Query/generation      model generation of the results (UInt32)
 *   Query/Result/<FP>/<ch>, Query/Summary/<s>/<TIF>   results (Float)
 *   Upload/<name>         the upload block (registers 40..51; written by
 *                         DCMD as a whole, like FC16)
 *   Status/points_present32, Status/points_required32   (registers 88..91)
 *   Query/x, Query/y      a locate (Float; written by DCMD)
 *   Query/kind, Query/locate_fail, Query/out_of_range   (registers 80..85)
 *   Net/Page/fp|ch|row    the coefficient page select (registers 96..98;
 *                         written by DCMD)
 *   Net/Page/values       the selected row (FloatArray, registers 384..)
 *   Net/<FP>/<ch>         whole nets up to SPB_NET_MAX values (FloatArray)
 *   Sample Grid/r<R>/c<C>/<T|I|F>   the sample grid (Float) */

#define N_QIN 2
#define N_QGEN 1
#define N_RES ((int)(IT2N_REGMAP_FP * IT2N_REGMAP_CH) + 12)
#define N_COUNTS 2
#define N_QLOC 2
#define N_QSTAT 3
#define N_PAGE 3
#define N_PAGEROW 1
#define N_NET ((int)(IT2N_REGMAP_FP * IT2N_REGMAP_CH))

static const it2n_regmap_block *block_at(unsigned start)
{
    for (size_t k = 0; k < it2n_regmap_nblocks; k++)
        if (it2n_regmap_blocks[k].start == start)
            return &it2n_regmap_blocks[k];
    return NULL;
}

static const it2n_regmap_block *status_block(void)
{
    return block_at(IT2N_REGMAP_REG_MAP_VERSION);
}

static const it2n_regmap_block *upload_block(void)
{
    return block_at(IT2N_REGMAP_REG_UP_I);
}

unsigned spb_metrics_upload_count(void)
{
    return (unsigned)upload_block()->nfields;
}

const it2n_regmap_field *spb_metrics_upload_field(int rel)
{
    return &upload_block()->fields[rel];
}

/* First index of each segment, and the count. */
static int seg_start(int seg)
{
    int n = 0;
    if (seg > SPB_SEG_STATUS)
        n += (int)status_block()->nfields;
    if (seg > SPB_SEG_QIN)
        n += N_QIN;
    if (seg > SPB_SEG_QGEN)
        n += N_QGEN;
    if (seg > SPB_SEG_RES)
        n += N_RES;
    if (seg > SPB_SEG_UPLOAD)
        n += (int)upload_block()->nfields;
    if (seg > SPB_SEG_COUNTS)
        n += N_COUNTS;
    if (seg > SPB_SEG_QLOC)
        n += N_QLOC;
    if (seg > SPB_SEG_QSTAT)
        n += N_QSTAT;
    if (seg > SPB_SEG_PAGE)
        n += N_PAGE;
    if (seg > SPB_SEG_PAGEROW)
        n += N_PAGEROW;
    if (seg > SPB_SEG_NET)
        n += N_NET;
    return n;
}

int spb_metrics_count(const struct mb_map_opts *o)
{
    return seg_start(SPB_SEG_GRID) + (int)(o->grid_rows * o->grid_cols) * 3;
}

/* The segment of idx, with idx made relative to it. */
int spb_metrics_seg(int *idx)
{
    for (int seg = SPB_SEG_GRID; seg > SPB_SEG_STATUS; seg--)
        if (*idx >= seg_start(seg)) {
            *idx -= seg_start(seg);
            return seg;
        }
    return SPB_SEG_STATUS;
}

static int field_type(int rt)
{
    switch (rt) {
    case IT2N_REGMAP_TYPE_I16: return SPB_PAYLOAD_INT16;
    case IT2N_REGMAP_TYPE_U32: return SPB_PAYLOAD_UINT32;
    case IT2N_REGMAP_TYPE_I32: return SPB_PAYLOAD_INT32;
    case IT2N_REGMAP_TYPE_F32: return SPB_PAYLOAD_FLOAT;
    default: return SPB_PAYLOAD_UINT16;
    }
}

int spb_metrics_type(int idx)
{
    switch (spb_metrics_seg(&idx)) {
    case SPB_SEG_STATUS: return field_type(status_block()->fields[idx].type);
    case SPB_SEG_QGEN: return SPB_PAYLOAD_UINT32;
    case SPB_SEG_UPLOAD: return field_type(upload_block()->fields[idx].type);
    case SPB_SEG_COUNTS: return SPB_PAYLOAD_UINT32;
    case SPB_SEG_QSTAT: return idx == 2 ? SPB_PAYLOAD_UINT32 : SPB_PAYLOAD_UINT16;
    case SPB_SEG_PAGE: return SPB_PAYLOAD_UINT16;
    case SPB_SEG_PAGEROW:
    case SPB_SEG_NET: return SPB_PAYLOAD_FLOATARRAY;
    default: return SPB_PAYLOAD_FLOAT;
    }
}

static const char *const fp_names[IT2N_REGMAP_FP] = {"LL", "LR", "L", "D", "R", "RL", "RR"};
static const char ch_names[IT2N_REGMAP_CH] = {'x', 'y', 'z', 'T', 'I', 'F'};
static const char *const sum_names[4] = {"upper_min", "upper_max", "lower_min", "lower_max"};

/* Name, and the description and unit for the birth. */
void spb_metrics_info(const struct mb_map_opts *o, int idx, char *name, size_t nsize, char *desc, size_t dsize,
                      const char **unit)
{
    static const char *const chname[3] = {"Truth", "Indeterminacy", "Falsity"};
    const it2n_regmap_field *f;
    unsigned nd, k, r, c;
    double u, w;
    int seg = spb_metrics_seg(&idx);
    *unit = NULL;
    switch (seg) {
    case SPB_SEG_STATUS:
    case SPB_SEG_UPLOAD:
        f = &(seg == SPB_SEG_STATUS ? status_block() : upload_block())->fields[idx];
        snprintf(name, nsize, "%s/%s", seg == SPB_SEG_STATUS ? "Status" : "Upload", f->name);
        snprintf(desc, dsize, "%s (Modbus register %u%s)", f->desc, (unsigned)f->addr,
                 seg == SPB_SEG_UPLOAD ? "; a DCMD writes the 9 Upload metrics together" : "");
        *unit = strcmp(f->unit, "-") ? f->unit : NULL;
        return;
    case SPB_SEG_QIN:
        snprintf(name, nsize, "Query/%c", idx ? 'w' : 'u');
        snprintf(desc, dsize,
                 "Parameter %c in [0, 1] of this device's query (Modbus q_%c_f, register %u); a DCMD "
                 "writing Query/u and/or Query/w evaluates the model there",
                 idx ? 'w' : 'u', idx ? 'w' : 'u', idx ? IT2N_REGMAP_REG_Q_WF : IT2N_REGMAP_REG_Q_UF);
        return;
    case SPB_SEG_QGEN:
        snprintf(name, nsize, "Query/generation");
        snprintf(desc, dsize, "Model generation the query results were computed from (Modbus q_generation)");
        return;
    case SPB_SEG_RES:
        if (idx < (int)(IT2N_REGMAP_FP * IT2N_REGMAP_CH)) {
            k = (unsigned)idx % IT2N_REGMAP_CH;
            snprintf(name, nsize, "Query/Result/%s/%c", fp_names[idx / (int)IT2N_REGMAP_CH], ch_names[k]);
            snprintf(desc, dsize,
                     "Surface value of footprint %s, channel %c at (Query/u, Query/w) (Modbus register "
                     "%u, float32)",
                     fp_names[idx / (int)IT2N_REGMAP_CH], ch_names[k], IT2N_REGMAP_REG_RES_F32 + 2u * (unsigned)idx);
            *unit = k < 3 ? "coord" : NULL;
        } else {
            idx -= (int)(IT2N_REGMAP_FP * IT2N_REGMAP_CH);
            snprintf(name, nsize, "Query/Summary/%s/%c", sum_names[idx / 3], "TIF"[idx % 3]);
            snprintf(desc, dsize, "Interval summary %s of %c at (Query/u, Query/w) (Modbus register %u, float32)",
                     sum_names[idx / 3], "TIF"[idx % 3], IT2N_REGMAP_REG_SUM_F32 + 2u * (unsigned)idx);
        }
        return;
    case SPB_SEG_COUNTS:
        f = &block_at(IT2N_REGMAP_REG_PRESENT32)->fields[idx];
        snprintf(name, nsize, "Status/%s", f->name);
        snprintf(desc, dsize, "%s (Modbus registers %u..%u)", f->desc, (unsigned)f->addr, f->addr + 1u);
        *unit = f->unit;
        return;
    case SPB_SEG_QLOC:
        snprintf(name, nsize, "Query/%c", idx ? 'y' : 'x');
        snprintf(desc, dsize,
                 "Locate: coordinate %c of this device's query (Modbus q_%c_f, register %u); a DCMD "
                 "writing Query/x and/or Query/y locates (x, y) on every footprint (the results are the surface "
                 "there); null unless the last query was a locate",
                 idx ? 'y' : 'x', idx ? 'y' : 'x', idx ? IT2N_REGMAP_REG_Q_YF : IT2N_REGMAP_REG_Q_XF);
        *unit = "coord";
        return;
    case SPB_SEG_QSTAT:
        f = &block_at(IT2N_REGMAP_REG_Q_KIND)->fields[idx == 0 ? 0 : idx + 1];
        snprintf(name, nsize, "Query/%s", idx == 0 ? "kind" : idx == 1 ? "locate_fail" : "out_of_range");
        snprintf(desc, dsize, "%s (Modbus %s, register %u)", f->desc, f->name, (unsigned)f->addr);
        *unit = strcmp(f->unit, "-") ? f->unit : NULL;
        return;
    case SPB_SEG_PAGE:
        f = &block_at(IT2N_REGMAP_REG_PG_FP)->fields[idx];
        snprintf(name, nsize, "Net/Page/%s", idx == 0 ? "fp" : idx == 1 ? "ch" : "row");
        snprintf(desc, dsize, "%s (Modbus %s, register %u; a DCMD selects the page Net/Page/values shows)", f->desc,
                 f->name, (unsigned)f->addr);
        return;
    case SPB_SEG_PAGEROW:
        snprintf(name, nsize, "Net/Page/values");
        snprintf(desc, dsize,
                 "Row Net/Page/row of net (Net/Page/fp, Net/Page/ch): Status/net_cols float32 values, "
                 "little-endian (Modbus coef_window, registers %u..); the control points of a Bezier model, the "
                 "coefficients c(r-1, s-1) of a B-spline; null while not solved",
                 IT2N_REGMAP_REG_WIN);
        *unit = "coord / 1";
        return;
    case SPB_SEG_NET:
        snprintf(name, nsize, "Net/%s/%c", fp_names[idx / (int)IT2N_REGMAP_CH], ch_names[idx % (int)IT2N_REGMAP_CH]);
        snprintf(desc, dsize,
                 "Whole net of footprint %s, channel %c, row by row (Status/net_rows x Status/net_cols "
                 "float32, little-endian; Modbus control_net / coef_window); null while not solved, for a footprint "
                 "the model does not carry, or above %u values (read those rows with Net/Page/...)",
                 fp_names[idx / (int)IT2N_REGMAP_CH], ch_names[idx % (int)IT2N_REGMAP_CH], SPB_NET_MAX);
        *unit = idx % (int)IT2N_REGMAP_CH < 3 ? "coord" : NULL;
        return;
    default:
        nd = (unsigned)idx / 3;
        k = (unsigned)idx % 3;
        r = nd / o->grid_cols;
        c = nd % o->grid_cols;
        u = o->grid_rows > 1 ? (double)r / (o->grid_rows - 1) : 0.0;
        w = o->grid_cols > 1 ? (double)c / (o->grid_cols - 1) : 0.0;
        snprintf(name, nsize, "Sample Grid/r%u/c%u/%c", r, c, "TIF"[k]);
        snprintf(desc, dsize, "%s membership of footprint D at u = %.4g, w = %.4g (Modbus register %u, float32)",
                 chname[k], u, w, IT2N_REGMAP_REG_GRID_F32 + (nd * 3 + k) * 2);
        return;
    }
}

/* Register fields of a block into metric values. */
static void fields_values(const it2n_regmap_block *b, const uint16_t *regs, struct spb_payload_val *out)
{
    for (size_t k = 0; k < b->nfields; k++) {
        const it2n_regmap_field *f = &b->fields[k];
        const uint16_t *r = &regs[f->addr - b->start];
        switch (f->type) {
        case IT2N_REGMAP_TYPE_I16: out[k].u = (uint64_t)(int64_t)(int16_t)r[0]; break;
        case IT2N_REGMAP_TYPE_U32: out[k].u = (uint32_t)r[0] << 16 | r[1]; break;
        case IT2N_REGMAP_TYPE_I32: out[k].u = (uint64_t)(int64_t)(int32_t)((uint32_t)r[0] << 16 | r[1]); break;
        case IT2N_REGMAP_TYPE_F32: out[k].f = it2n_regmap_get_f32(r, IT2N_REGMAP_WO_ABCD); break;
        default: out[k].u = r[0]; break;
        }
    }
}

static void set_null(struct spb_payload_val *out, int n)
{
    for (int k = 0; k < n; k++)
        out[k].null = 1;
}

/* float32 registers (ABCD) into the packed little-endian bytes of a
 * FloatArray, with the hash that stands for the value (FNV-1a, 64 bit). */
static void float_array(const uint16_t *regs, unsigned n, uint8_t *bytes, struct spb_payload_val *out)
{
    uint64_t h = 14695981039346656037u;
    for (unsigned k = 0; k < n; k++) {
        float f = it2n_regmap_get_f32(&regs[2 * k], IT2N_REGMAP_WO_ABCD);
        uint32_t bits;
        memcpy(&bits, &f, sizeof bits);
        for (unsigned b = 0; b < 4; b++)
            bytes[4 * k + b] = (uint8_t)(bits >> (8 * b));
    }
    for (unsigned k = 0; k < 4 * n; k++)
        h = (h ^ bytes[k]) * 1099511628211u;
    out->u = h ^ n;
    out->b = bytes;
    out->nb = 4u * n;
}

/* The nets: Net/Page/values and the whole nets, read through the
 * coefficient window like a PLC, page by page (a scratch page select:
 * the device's own stays as a DCMD set it). */
static void net_values(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o, unsigned rows,
                       unsigned cols, struct spb_payload_val *out)
{
    static uint16_t regs[2 * IT2N_REGMAP_WIN_COLS];
    static uint8_t page_bytes[4 * IT2N_REGMAP_WIN_COLS];
    static uint8_t net_bytes[N_NET][4 * SPB_NET_MAX];
    struct mb_map_query scratch;
    if (!cols || mb_map_read(md, q, o, IT2N_REGMAP_REG_WIN, 2u * cols, regs) != MB_MAP_OK)
        out[0].null = 1;
    else
        float_array(regs, cols, page_bytes, &out[0]);
    out++;
    for (int k = 0; k < N_NET; k++) {
        unsigned fp = (unsigned)k / IT2N_REGMAP_CH, ch = (unsigned)k % IT2N_REGMAP_CH;
        static uint16_t net[2 * SPB_NET_MAX];
        int ok = rows && cols && rows * cols <= SPB_NET_MAX && models_has_fp(md, fp);
        scratch = *q;
        for (unsigned r = 0; ok && r < rows; r++) {
            uint16_t page[3] = {(uint16_t)fp, (uint16_t)ch, (uint16_t)r};
            memcpy(scratch.page, page, sizeof page);
            ok = mb_map_read(md, &scratch, o, IT2N_REGMAP_REG_WIN, 2u * cols, &net[2 * r * cols]) == MB_MAP_OK;
        }
        if (ok)
            float_array(net, rows * cols, net_bytes[k], &out[k]);
        else
            out[k].null = 1;
    }
}

/* The values a PLC reads now, through the same register map code, from
 * the last durable state: the status block, this device's query (its own
 * connection-like state) and results, the upload block, the float32
 * sample grid. Null where Modbus answers an exception (not solved). */
void spb_metrics_values(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o,
                        struct spb_payload_val *out)
{
    static uint16_t regs[IT2N_REGMAP_REG_GRID_F32_END - IT2N_REGMAP_REG_GRID_F32];
    const it2n_regmap_block *b = status_block(), *up = upload_block();
    unsigned nodes = o->grid_rows * o->grid_cols;
    int n = spb_metrics_count(o);
    memset(out, 0, (size_t)n * sizeof *out);
    if (mb_map_read(md, q, o, b->start, (unsigned)(b->end - b->start), regs) == MB_MAP_OK)
        fields_values(b, regs, out);
    else
        set_null(out, (int)b->nfields);
    out += seg_start(SPB_SEG_QIN);
    if (q->kind == 1 && mb_map_read(md, q, o, IT2N_REGMAP_REG_Q_UF, 4, regs) == MB_MAP_OK) {
        out[0].f = it2n_regmap_get_f32(&regs[0], IT2N_REGMAP_WO_ABCD);
        out[1].f = it2n_regmap_get_f32(&regs[2], IT2N_REGMAP_WO_ABCD);
    } else {
        set_null(out, N_QIN);
    }
    out += N_QIN;
    if (q->kind && mb_map_read(md, q, o, IT2N_REGMAP_REG_Q_GEN, 2, regs) == MB_MAP_OK &&
        mb_map_read(md, q, o, IT2N_REGMAP_REG_RES_F32, 2u * (unsigned)N_RES, regs + 2) == MB_MAP_OK) {
        out[0].u = (uint32_t)regs[0] << 16 | regs[1];
        for (int k = 0; k < N_RES; k++)
            out[1 + k].f = it2n_regmap_get_f32(&regs[2 + 2 * k], IT2N_REGMAP_WO_ABCD);
    } else {
        set_null(out, N_QGEN + N_RES); /* no query yet, or not solved (06) */
    }
    out += N_QGEN + N_RES;
    if (mb_map_read(md, q, o, up->start, (unsigned)(up->end - up->start), regs) == MB_MAP_OK)
        fields_values(up, regs, out);
    else
        set_null(out, (int)up->nfields);
    out += up->nfields;
    if (mb_map_read(md, q, o, IT2N_REGMAP_REG_PRESENT32, 4, regs) == MB_MAP_OK)
        fields_values(block_at(IT2N_REGMAP_REG_PRESENT32), regs, out);
    else
        set_null(out, N_COUNTS);
    out += N_COUNTS;
    if (q->kind == 2 && mb_map_read(md, q, o, IT2N_REGMAP_REG_Q_XF, 4, regs) == MB_MAP_OK) {
        out[0].f = it2n_regmap_get_f32(&regs[0], IT2N_REGMAP_WO_ABCD);
        out[1].f = it2n_regmap_get_f32(&regs[2], IT2N_REGMAP_WO_ABCD);
    } else {
        set_null(out, N_QLOC);
    }
    out += N_QLOC;
    /* q_kind reads while unsolved; the bits only with a result. */
    memset(regs, 0, 6 * sizeof *regs);
    if (mb_map_read(md, q, o, IT2N_REGMAP_REG_Q_KIND, 6, regs) == MB_MAP_OK)
        out[0].u = regs[0];
    else
        out[0].null = 1;
    if (q->kind && mb_map_read(md, q, o, IT2N_REGMAP_REG_RES_F32, 2, regs + 8) == MB_MAP_OK) {
        out[1].u = regs[IT2N_REGMAP_REG_Q_LOCFAIL - IT2N_REGMAP_REG_Q_KIND];
        out[2].u = (uint32_t)regs[IT2N_REGMAP_REG_Q_OOR - IT2N_REGMAP_REG_Q_KIND] << 16 |
                   regs[IT2N_REGMAP_REG_Q_OOR - IT2N_REGMAP_REG_Q_KIND + 1];
    } else {
        set_null(out + 1, 2);
    }
    out += N_QSTAT;
    if (mb_map_read(md, q, o, IT2N_REGMAP_REG_PG_FP, 3, regs) == MB_MAP_OK)
        for (int k = 0; k < N_PAGE; k++)
            out[k].u = regs[k];
    else
        set_null(out, N_PAGE);
    out += N_PAGE;
    {
        unsigned rows = 0, cols = 0;
        if (mb_map_read(md, q, o, IT2N_REGMAP_REG_NET_ROWS, 2, regs) == MB_MAP_OK) {
            rows = regs[0];
            cols = regs[1];
        }
        net_values(md, q, o, rows, cols, out);
    }
    out += N_PAGEROW + N_NET;
    if (!nodes)
        return;
    if (mb_map_read(md, q, o, IT2N_REGMAP_REG_GRID_F32, nodes * 6u, regs) != MB_MAP_OK) {
        set_null(out, (int)nodes * 3); /* not solved: no grid (Modbus answers 06) */
        return;
    }
    for (unsigned k = 0; k < nodes * 3u; k++)
        out[k].f = it2n_regmap_get_f32(&regs[k * 2], IT2N_REGMAP_WO_ABCD);
}
