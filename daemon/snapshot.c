/* snapshot.c — see snapshot.h.
 *
 * File: header (32 bytes)
 *   0 "IT2NSNP\0", 8 u32 version (2, 3 or 4), 12 u32 0, 16 u64 seq,
 *   24 u32 models, 28 u32 0
 * per model (version 2: 44 bytes, versions 3, 4: 48, then its points)
 *   0 u16 id, 2 u8 n, 3 u8 m, 4 u8 flags, 5 u8 state, 6 u16 points,
 *   8 u32 generation, 12 u32 points_rx, 16 u32 solves, 20 12 x u16 upload,
 *   versions 3, 4: 44 u8 kind (0 Bezier, 1 B-spline), 45 u8 0,
 *   46 u16 points (high half: a 256 x 256 grid has 65536)
 * Version 3 is written only when a model is of the B-spline kind, so a
 * Bezier-only state directory stays readable by older builds; version 4
 * (as 3, memberships in Q30) only when a stored membership is not
 * Q24-exact (uploaded over Modbus, the paper's preload), so state that
 * older builds could hold is still written for them.
 * per grid point holding at least one footprint
 *   0 u8 i, 1 u8 j, 2 u8 mask (bit fp), then for each fp in mask, in
 *   order, 6 x i64 (x, y, z, T, I, F) Q24 (version 4: T, I, F Q30)
 * trailer: u32 CRC-32C of everything before it. All little-endian. */
#include "snapshot.h"

#include <stdlib.h>
#include <string.h>

#include "it2n_proto.h"
#include "log.h"
#include "le_bytes.h"
#include "models.h"
#include "store.h"

#define MODEL_HDR_V2 44u
#define MODEL_HDR_V3 48u
#define UPLOAD_WORDS (IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I)
#define FP_BYTES (8u * IT2N_CH_COUNT)

_Static_assert(UPLOAD_WORDS == 12, "snapshot model header holds 12 upload registers");
_Static_assert(IT2N_FP_COUNT <= 8, "footprint mask is one byte");

static unsigned popcount8(unsigned v)
{
    unsigned c = 0;
    for (; v; v &= v - 1)
        c++;
    return c;
}

size_t snapshot_max_size(int nmodels)
{
    return SNAPSHOT_HDR + 4 +
           (size_t)nmodels * (MODEL_HDR_V3 + (size_t)IT2N_DIM * IT2N_DIM * (3 + FP_BYTES * IT2N_FP_COUNT));
}

size_t snapshot_max_size_bspline(void)
{
    size_t size = 0;
    for (int k = 0; k < models_count(); k++) {
        const struct model *md = models_at(k);
        if (md->kind == MODEL_BSPLINE)
            size += MODEL_HDR_V3 + (size_t)(md->cap_n + 1u) * (md->cap_m + 1u) * (3 + FP_BYTES * IT2N_FP_COUNT);
    }
    return size;
}

/* The footprint mask of grid point (i, j). */
static unsigned point_mask(const struct model *md, unsigned i, unsigned j)
{
    unsigned mask = 0;
    for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
        if (models_point_present(md, i, j, fp))
            mask |= 1u << fp;
    return mask;
}

/* A membership of md that Q24 cannot hold exactly. */
static int needs_fine(const struct model *md)
{
    for (unsigned i = 0; i <= models_n(md); i++)
        for (unsigned j = 0; j <= models_m(md); j++)
            for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_val v[IT2N_CH_COUNT];
                if (!models_point_present(md, i, j, fp))
                    continue;
                models_point_get_fine(md, i, j, fp, v);
                for (unsigned c = IT2N_CH_T; c < IT2N_CH_COUNT; c++)
                    if (v[c] & ((1 << (IT2N_MEMB_FRAC - IT2N_VAL_FRAC)) - 1))
                        return 1;
            }
    return 0;
}

/* durable_view: encode models_view() of each model (the last durable
 * state, while a batch is gathered or in flight), else the models. */
uint8_t *snapshot_encode(uint64_t seq, size_t *len, int durable_view)
{
    size_t size = SNAPSHOT_HDR + 4, off, mhdr;
    int n = models_count();
    unsigned version = SNAPSHOT_VERSION_BEZIER;
    uint8_t *buf;
    for (int k = 0; k < n; k++)
        if (models_at(k)->kind != MODEL_BEZIER)
            version = SNAPSHOT_VERSION;
    for (int k = 0; k < n && version != SNAPSHOT_VERSION_FINE; k++)
        if (needs_fine(durable_view ? models_view(models_at(k)) : models_at(k)))
            version = SNAPSHOT_VERSION_FINE;
    mhdr = version == SNAPSHOT_VERSION_BEZIER ? MODEL_HDR_V2 : MODEL_HDR_V3;
    for (int k = 0; k < n; k++) {
        const struct model *md = durable_view ? models_view(models_at(k)) : models_at(k);
        size += mhdr;
        for (unsigned i = 0; i <= models_n(md); i++)
            for (unsigned j = 0; j <= models_m(md); j++) {
                unsigned mask = point_mask(md, i, j);
                if (mask)
                    size += 3 + FP_BYTES * popcount8(mask);
            }
    }
    buf = calloc(1, size);
    if (!buf)
        return NULL;
    memcpy(buf, SNAPSHOT_MAGIC, 8);
    le_put32(buf + 8, version);
    le_put64(buf + 16, seq);
    le_put32(buf + 24, (uint32_t)n);
    off = SNAPSHOT_HDR;
    for (int k = 0; k < n; k++) {
        const struct model *md = durable_view ? models_view(models_at(k)) : models_at(k);
        uint8_t *h = buf + off;
        uint32_t points = 0;
        off += mhdr;
        for (unsigned i = 0; i <= models_n(md); i++)
            for (unsigned j = 0; j <= models_m(md); j++) {
                unsigned mask = point_mask(md, i, j);
                it2n_val v[IT2N_CH_COUNT];
                if (!mask)
                    continue;
                points++;
                buf[off++] = (uint8_t)i;
                buf[off++] = (uint8_t)j;
                buf[off++] = (uint8_t)mask;
                for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
                    if (mask & (1u << fp)) {
                        if (version == SNAPSHOT_VERSION_FINE)
                            models_point_get_fine(md, i, j, fp, v);
                        else
                            models_point_get(md, i, j, fp, v); /* exact */
                        for (unsigned c = 0; c < IT2N_CH_COUNT; c++, off += 8)
                            le_put64(buf + off, (uint64_t)v[c]);
                    }
            }
        le_put16(h, (unsigned)md->id);
        h[2] = (uint8_t)models_n(md);
        h[3] = (uint8_t)models_m(md);
        h[4] = (uint8_t)models_flags(md);
        h[5] = (uint8_t)md->state;
        le_put16(h + 6, points & 0xFFFFu);
        if (version != SNAPSHOT_VERSION_BEZIER) {
            h[44] = (uint8_t)md->kind;
            le_put16(h + 46, points >> 16);
        }
        le_put32(h + 8, md->gen);
        le_put32(h + 12, md->points_rx);
        le_put32(h + 16, md->solves);
        for (unsigned w = 0; w < UPLOAD_WORDS; w++)
            le_put16(h + 20 + 2 * w, md->mb.upload[w]);
    }
    le_put32(buf + off, it2n_crc32c(buf, off));
    *len = off + 4;
    return buf;
}

/* The point count of a model record. */
static uint32_t model_points(const uint8_t *h, size_t mhdr)
{
    return le_get16(h + 6) | (mhdr == MODEL_HDR_V3 ? (uint32_t)le_get16(h + 46) << 16 : 0u);
}

/* Walk the model records without using them: every length must add up. */
static int check_structure(const uint8_t *buf, size_t len, uint32_t nmodels, size_t mhdr)
{
    size_t off = SNAPSHOT_HDR, end = len - 4;
    for (uint32_t k = 0; k < nmodels; k++) {
        if (end - off < mhdr)
            return -1;
        uint32_t points = model_points(buf + off, mhdr);
        if (mhdr == MODEL_HDR_V3 && (buf[off + 44] > MODEL_BSPLINE || buf[off + 45]))
            return -1;
        off += mhdr;
        for (uint32_t p = 0; p < points; p++) {
            if (end - off < 3 || (buf[off + 2] & ~((1u << IT2N_FP_COUNT) - 1u)) || !buf[off + 2])
                return -1;
            size_t body = FP_BYTES * popcount8(buf[off + 2]);
            off += 3;
            if (end - off < body)
                return -1;
            off += body;
        }
    }
    return off == end ? 0 : -1;
}

/* One entry into a data set of either kind: fine, memberships in Q30. */
typedef int (*put_fn)(void *set, unsigned i, unsigned j, unsigned fp, const it2n_val *v, int fine, it2n_errinfo *err);

static int put_bezier(void *set, unsigned i, unsigned j, unsigned fp, const it2n_val *v, int fine, it2n_errinfo *err)
{
    return fine ? it2n_dataset_put_fine(set, i, j, fp, v, false, err) : it2n_dataset_put(set, i, j, fp, v, false, err);
}

static int put_bspline(void *set, unsigned i, unsigned j, unsigned fp, const it2n_val *v, int fine, it2n_errinfo *err)
{
    return fine ? it2n_bspline_data_put_fine(set, i, j, fp, v, false, err)
                : it2n_bspline_data_put(set, i, j, fp, v, false, err);
}

/* The point records at p (i, j, footprint mask, then 8 bytes per channel
 * of each footprint in the mask; their lengths checked before) into set,
 * one put per entry. IT2N_OK or the first refusal. */
static int load_points(const uint8_t *p, uint32_t points, int fine, put_fn put, void *set, it2n_errinfo *err)
{
    int rc = IT2N_OK;
    for (uint32_t k = 0; k < points && rc == IT2N_OK; k++) {
        unsigned i = p[0], j = p[1], mask = p[2];
        p += 3;
        for (unsigned fp = 0; fp < IT2N_FP_COUNT && rc == IT2N_OK; fp++) {
            it2n_val v[IT2N_CH_COUNT];
            if (!(mask & (1u << fp)))
                continue;
            for (unsigned c = 0; c < IT2N_CH_COUNT; c++, p += 8)
                v[c] = (it2n_val)le_get64(p);
            rc = put(set, i, j, fp, v, fine, err);
        }
    }
    return rc;
}

/* Rebuild md (kind B-spline) from the points at p: data set into a
 * scratch copy of md's storage, solved if state says so, then copied in.
 * IT2N_OK or the core's refusal (md unchanged). */
static int load_bspline(struct model *md, unsigned n, unsigned m, unsigned flags, unsigned state, uint32_t points,
                        const uint8_t *p, int fine, it2n_errinfo *err)
{
    it2n_bspline_rec *rec = malloc(md->bds.cap * sizeof *rec);
    int32_t *coef = malloc(md->bmdl.cap * sizeof *coef);
    it2n_bspline_data ds;
    it2n_bspline_model mdl;
    int rc = IT2N_ERR_STATE;
    if (!rec || !coef) {
        free(rec);
        free(coef);
        return SNAPSHOT_NOMEM;
    }
    rc = it2n_bspline_data_init(&ds, rec, md->bds.cap, n, m, flags, err);
    if (rc == IT2N_OK)
        rc = load_points(p, points, fine, put_bspline, &ds, err);
    it2n_bspline_model_init(&mdl, coef, md->bmdl.cap);
    if (rc == IT2N_OK && state == IT2N_REGMAP_STATE_SOLVED)
        rc = it2n_bspline_solve(&mdl, &ds, err);
    if (rc == IT2N_OK) {
        memcpy(md->bds.rec, rec, md->bds.cap * sizeof *rec);
        memcpy(md->bmdl.coef, coef, md->bmdl.cap * sizeof *coef);
        md->bds.n = ds.n;
        md->bds.m = ds.m;
        md->bds.flags = ds.flags;
        mdl.coef = md->bmdl.coef;
        md->bmdl = mdl;
    }
    free(rec);
    free(coef);
    return rc;
}

/* Rebuild one model from its record at buf (structure already checked).
 * Returns the record's length; *rc = 0, SNAPSHOT_BAD_MODEL, SNAPSHOT_NOMEM or
 * SNAPSHOT_UNCONFIGURED. */
static size_t load_model(const uint8_t *buf, size_t mhdr, int fine, int *result)
{
    unsigned id = le_get16(buf), n = buf[2], m = buf[3], flags = buf[4], state = buf[5];
    unsigned kind = mhdr == MODEL_HDR_V3 ? buf[44] : MODEL_BEZIER;
    uint32_t points = model_points(buf, mhdr);
    const uint8_t *p = buf + mhdr;
    size_t rlen = mhdr;
    struct model *md = models_by_id((int)id);
    it2n_dataset *ds = NULL;
    it2n_model *mdl = NULL;
    it2n_errinfo err;
    int rc = IT2N_OK;
    const char *why = NULL;

    memset(&err, 0, sizeof err);
    err.i = err.j = -1;
    err.fp = -1;
    *result = 0;
    for (uint32_t k = 0; k < points; k++)
        rlen += 3 + FP_BYTES * popcount8(buf[rlen + 2]);
    if (!md) {
        if (points && !store_may_drop((int)id, points, "snapshot")) {
            *result = SNAPSHOT_UNCONFIGURED;
            return rlen;
        }
        log_warn("snapshot: model %u no longer configured; dropped", id);
        return rlen;
    }
    if (kind != (unsigned)md->kind) {
        /* The configuration changed the kind while the daemon was down:
         * points of the other kind cannot go in, and are not dropped
         * unasked. */
        if (points) {
            log_err("snapshot: model %u holds %u data point(s) of kind %s, but [model:%u] now says kind = %s; "
                    "set the kind back, or remove the model with 'removed = yes' to discard them (docs/daemon.md); "
                    "refusing to start, files left as they are",
                    id, (unsigned)points, models_kind_name((int)kind), id, models_kind_name(md->kind));
            *result = SNAPSHOT_UNCONFIGURED;
            return rlen;
        }
        log_notice("snapshot: model %u was of kind %s with no data points; now %s", id, models_kind_name((int)kind),
                   models_kind_name(md->kind));
        return rlen;
    }
    if (kind == MODEL_BSPLINE && (n > md->cap_n || m > md->cap_m)) {
        /* The configuration shrank the model's storage while the daemon
         * was down: its points do not fit, and are not dropped unasked. */
        if (points) {
            log_err("snapshot: B-spline model %u holds %u data point(s) of a %ux%u grid, beyond the n = %u, m = %u "
                    "its [model:%u] section now gives it; raise n and m there (or remove the model with "
                    "'removed = yes' to discard them); refusing to start, files left as they are",
                    id, (unsigned)points, n, m, md->cap_n, md->cap_m, id);
            *result = SNAPSHOT_UNCONFIGURED;
            return rlen;
        }
        log_notice("snapshot: B-spline model %u was %ux%u with no data points; now at most %ux%u", id, n, m, md->cap_n,
                   md->cap_m);
        return rlen;
    }
    if (kind == MODEL_BEZIER && (n > IT2N_MAX_DEGREE || m > IT2N_MAX_DEGREE)) {
        log_err("snapshot: model %u is %ux%u, beyond this build's IT2N_MAX_DEGREE %d; dropped", id, n, m,
                IT2N_MAX_DEGREE);
        return rlen;
    }
    if (state > IT2N_REGMAP_STATE_FAILED) { /* IT2N_REGMAP_STATE_EMPTY is 0 */
        log_err("snapshot: model %u has unknown state %u", id, state);
        *result = SNAPSHOT_BAD_MODEL;
        return rlen;
    }
    if (state == IT2N_REGMAP_STATE_EMPTY && points) {
        why = "points in an empty model";
        goto out;
    }
    if (kind == MODEL_BSPLINE) {
        rc = load_bspline(md, n, m, flags, state, points, p, fine, &err);
        if (rc == SNAPSHOT_NOMEM) {
            log_err("snapshot: model %u: no memory to rebuild it", id);
            *result = SNAPSHOT_NOMEM;
            return rlen;
        }
        if (rc != IT2N_OK) {
            why = it2n_strerror(rc);
            goto out;
        }
        goto counters;
    }
    ds = malloc(sizeof *ds);
    mdl = malloc(sizeof *mdl);
    if (!ds || !mdl) {
        log_err("snapshot: model %u: no memory to rebuild it", id);
        *result = SNAPSHOT_NOMEM;
        goto out;
    }
    rc = it2n_dataset_init(ds, n, m, flags, &err);
    if (rc == IT2N_OK)
        rc = load_points(p, points, fine, put_bezier, ds, &err);
    if (rc != IT2N_OK) {
        why = it2n_strerror(rc);
        goto out;
    }
    it2n_model_init(mdl);
    if (state == IT2N_REGMAP_STATE_SOLVED) {
        /* The control nets are derived: solve again (bit-identical to the
         * incremental updates that produced them). */
        rc = it2n_model_solve(mdl, ds, &err);
        if (rc != IT2N_OK) {
            why = it2n_strerror(rc);
            goto out;
        }
    }
    md->ds = *ds;
    md->mdl = *mdl;
counters:
    md->state = (int)state;
    md->gen = le_get32(buf + 8);
    md->points_rx = le_get32(buf + 12);
    md->solves = le_get32(buf + 16);
    for (unsigned w = 0; w < UPLOAD_WORDS; w++)
        md->mb.upload[w] = (uint16_t)le_get16(buf + 20 + 2 * w);
out:
    if (why) {
        log_err("snapshot: model %u does not validate (%s at i %d j %d fp %d)", id, why, err.i, err.j, err.fp);
        *result = SNAPSHOT_BAD_MODEL;
    }
    free(ds);
    free(mdl);
    return rlen;
}

int snapshot_decode(const uint8_t *buf, size_t len, uint64_t *seq)
{
    uint32_t n, version;
    size_t off = SNAPSHOT_HDR, mhdr;
    if (len < SNAPSHOT_HDR + 4 || memcmp(buf, SNAPSHOT_MAGIC, 8))
        return SNAPSHOT_BAD;
    version = le_get32(buf + 8);
    if (version != SNAPSHOT_VERSION && version != SNAPSHOT_VERSION_BEZIER && version != SNAPSHOT_VERSION_FINE)
        return SNAPSHOT_BAD;
    mhdr = version == SNAPSHOT_VERSION_BEZIER ? MODEL_HDR_V2 : MODEL_HDR_V3;
    if (le_get32(buf + len - 4) != it2n_crc32c(buf, len - 4)) {
        log_err("snapshot: truncated or checksum mismatch (%zu bytes)", len);
        return SNAPSHOT_BAD;
    }
    n = le_get32(buf + 24);
    if (check_structure(buf, len, n, mhdr)) {
        log_err("snapshot: records do not add up to the file length");
        return SNAPSHOT_BAD;
    }
    for (uint32_t k = 0; k < n; k++) {
        int rc;
        off += load_model(buf + off, mhdr, version == SNAPSHOT_VERSION_FINE, &rc);
        if (rc)
            return rc;
    }
    *seq = le_get64(buf + 16);
    log_info("snapshot: version %u, %u model(s), seq %llu", version, n, (unsigned long long)*seq);
    return 0;
}
