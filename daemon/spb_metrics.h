/* spb_metrics — the Sparkplug metrics of a Device model-N (docs/sparkplug.md,
 * "Metrics"): their order, names, datatypes and descriptions, and their
 * values read through the register map code (mb_map.c) from a model, so a
 * SCADA and a PLC see the same numbers. The list depends only on the
 * register map and the configured grid size, never on a model's state.
 * No I/O, no state of its own. */
#ifndef IT2ND_SPB_METRICS_H
#define IT2ND_SPB_METRICS_H

#include <stddef.h>

#include "it2n_regmap.h"
#include "mb_map.h"
#include "models.h"
#include "spb_payload.h"

/* Metric K of model N has the alias (N + 1) * SPB_DEV_ALIAS + K. */
#define SPB_DEV_ALIAS 10000u

/* Nets carried whole (the Net/<FP>/<ch> arrays) up to this many values
 * (rows x columns): every Bezier net (8 x 8 at most) and B-spline nets up
 * to 5 x 5 intervals. A birth then carries 42 x 64 x 4 bytes of nets at
 * most; larger nets are read a row at a time (Net/Page/...). */
#define SPB_NET_MAX 64u

/* The segments of the list, in order. */
enum spb_seg {
    SPB_SEG_STATUS,  /* Status/<field>: registers 0..31           */
    SPB_SEG_QIN,     /* Query/u, Query/w                          */
    SPB_SEG_QGEN,    /* Query/generation                          */
    SPB_SEG_RES,     /* Query/Result/..., Query/Summary/...       */
    SPB_SEG_UPLOAD,  /* Upload/<field>: registers 40..51          */
    SPB_SEG_COUNTS,  /* Status/points_present32, .._required32    */
    SPB_SEG_QLOC,    /* Query/x, Query/y (a locate)               */
    SPB_SEG_QSTAT,   /* Query/kind, locate_fail, out_of_range     */
    SPB_SEG_PAGE,    /* Net/Page/fp, ch, row (the page select)    */
    SPB_SEG_PAGEROW, /* Net/Page/values (the coefficient window)  */
    SPB_SEG_NET,     /* Net/<FP>/<ch>: whole nets, FloatArray     */
    SPB_SEG_GRID     /* Sample Grid/r<R>/c<C>/<T|I|F>             */
};

/* Metrics of a device with o's grid size. */
int spb_metrics_count(const struct mb_map_opts *o);

/* The segment of metric *idx; *idx becomes its index in the segment. */
int spb_metrics_seg(int *idx);

/* The Sparkplug datatype of metric idx (enum spb_payload_type). */
int spb_metrics_type(int idx);

/* Name, description and unit (NULL: none) of metric idx. */
void spb_metrics_info(const struct mb_map_opts *o, int idx, char *name, size_t nsize, char *desc, size_t dsize,
                      const char **unit);

/* Every metric's value now (spb_metrics_count(o) of them into out): md
 * as readers see it (pass models_view()), q the device's query (its
 * results are cached in it). Null where Modbus answers an exception. */
void spb_metrics_values(struct model *md, struct mb_map_query *q, const struct mb_map_opts *o,
                        struct spb_payload_val *out);

/* The fields of the upload block (the Upload metrics, in order). */
unsigned spb_metrics_upload_count(void);
const it2n_regmap_field *spb_metrics_upload_field(int rel);

#endif
