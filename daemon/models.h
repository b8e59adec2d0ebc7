/* models — the model table: per model id a staging data set and a solved
 * it2n_model. Points PUT before the model is complete go to the data set;
 * completion or COMMIT solves with it2n_model_solve; PUTs into a solved
 * model use it2n_model_update (data set and model change together). Every
 * accepted change is reported to the journal hook (the WAL) before the
 * caller acknowledges it; a rejected change leaves the model exactly as it
 * was.
 *
 * Undo log, not copies: an operation records in an undo log the bytes it
 * is about to overwrite (the model's header; for a data point the point
 * and the nets of the footprints the core re-solves; the whole data set
 * or net only where the operation rewrites it: configure, clear, a
 * solve). Rolling back (a failed operation, a transaction, a batch whose
 * commit failed) copies them back in reverse order, so the model is
 * restored bit for bit. No operation copies the whole model. */
#ifndef IT2ND_MODELS_H
#define IT2ND_MODELS_H

#include <stddef.h>
#include <stdint.h>

#include "it2n.h"
#include "it2n_regmap.h"

/* The Modbus side of a model (daemon/mb_req.c, mb_map.c; the links use
 * none of it): the request/exception counters of the status block (live,
 * never rolled back) and the upload block as last written (registers
 * 40..51, kept in snapshots). The sample grid cache is mb_map.c's own. */
struct model_modbus {
    uint32_t requests, exceptions;
    uint16_t upload[IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I];
};

/* Model kinds ([model:ID] kind; Modbus status register kind). */
enum model_kind { MODEL_BEZIER = 0, MODEL_BSPLINE = 1 };

struct model {
    /* The header: every scalar of the model (an operation records it
     * whole in the undo log, MODEL_HDR_BYTES). */
    int id, unit;
    int kind;              /* enum model_kind, fixed by the configuration */
    size_t bytes;          /* of the allocation (struct + B-spline storage) */
    unsigned cap_n, cap_m; /* B-spline: the largest grid the storage holds */
    uint32_t instance;     /* unique per models_add and batch rollback (cache keys) */
    int state;             /* enum it2n_regmap_state              */
    uint32_t gen;          /* bumped on every solve and update    */
    it2n_errinfo last_err; /* code 0 = none                       */
    int last_op;           /* enum model_op of the last change     */
    uint32_t points_rx, solves;
    struct model_modbus mb;
    /* The data. */
    it2n_dataset ds; /* Bezier: current data (staging and solved) */
    it2n_model mdl;  /* Bezier: valid when state == IT2N_REGMAP_STATE_SOLVED */
    /* B-spline kind: data set and model over the storage that follows the
     * struct in the same allocation (records, then coefficients; sized by
     * the core's macros for cap_n x cap_m with every footprint and z), so
     * the undo log's offsets from the model reach them too. Unused (zero)
     * for a Bezier model. */
    it2n_bspline_data bds;
    it2n_bspline_model bmdl;
};

#define MODEL_HDR_BYTES offsetof(struct model, ds)

/* Journal record kinds (also the WAL record types). */
enum model_op { MOP_CONFIG = 1, MOP_POINT = 2, MOP_COMMIT = 3, MOP_CLEAR = 4 };

struct model_rec {
    int op;
    int id;
    unsigned n, m, flags, kind;   /* MOP_CONFIG */
    unsigned i, j, fp;            /* MOP_POINT  */
    it2n_val vals[IT2N_CH_COUNT]; /* MOP_POINT: Q24, or the fine layout */
    bool replace;                 /* MOP_POINT  */
    bool fine;                    /* MOP_POINT: T, I, F in Q30 (it2n.h) */
};

/* Called for every accepted change; a non-zero return (a negative
 * IT2ND_ERR_* code, errs.h) rejects it (e.g. the WAL cannot take it), in
 * which case the model is rolled back and its last_error set to the code. */
typedef int (*model_journal_fn)(void *arg, const struct model_rec *rec);

/* Create the table with room for max models. Returns 0 or -1. */
int models_init(int max);
void models_free(void);
void models_set_journal(model_journal_fn fn, void *arg);

/* Add a model (id unique, unit unique) of kind (enum model_kind). A
 * B-spline model's storage holds n x m intervals with every footprint and
 * z (models_bytes): a later CONFIGURE may choose any size up to that.
 * Returns it, or NULL. */
struct model *models_add(int id, int unit, int kind, unsigned n, unsigned m, unsigned flags);
/* Bytes one model of kind and n x m intervals takes in the daemon (its
 * allocation; the readers' view buffer takes as much again). */
size_t models_bytes(int kind, unsigned n, unsigned m);
/* "bezier" or "bspline". */
const char *models_kind_name(int kind);
/* Remove a model from the table and free it (reload). Must not be called
 * with a pass in progress (models_pass_dirty()). */
void models_remove(struct model *md);
struct model *models_by_id(int id);
struct model *models_by_unit(int unit);
int models_count(void);
struct model *models_at(int k);

/* Load the paper's example data set (n = m = 3) and solve. Not journaled:
 * it is part of the configuration. Returns an it2n error code. */
int models_preload_paper(struct model *md);

/* Operations. Return IT2N_OK or a negative it2n error code; err filled. A
 * journal or memory failure returns the daemon's code (IT2ND_ERR_IO,
 * IT2ND_ERR_DEGRADED, IT2ND_ERR_NOMEM; errs.h) with nothing changed and
 * last_error set. After a failed group commit models_pass_end(0) sets
 * last_error to IT2ND_ERR_IO on every model it puts back. */
int models_configure(struct model *md, unsigned n, unsigned m, unsigned flags, it2n_errinfo *err);
/* replace false: an entry already present fails with IT2N_ERR_DUPLICATE.
 * vals in Q24 (what the serial protocol carries). */
int models_put(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT], bool replace,
               it2n_errinfo *err);
/* The same with vals in the core's fine layout (T, I, F in Q30,
 * it2n_dataset_put_fine): the Modbus upload (x 10000 memberships) and the
 * paper's decimals, so the daemon holds what 'it2n' reads from the same
 * CSV. Journaled as such (store.c). */
int models_put_fine(struct model *md, unsigned i, unsigned j, unsigned fp, const it2n_val vals[IT2N_CH_COUNT],
                    bool replace, it2n_errinfo *err);
int models_commit(struct model *md, it2n_errinfo *err);
int models_clear(struct model *md);

/* Transactions (begin / commit / rollback): a group of operations that is
 * all or nothing, such as a Modbus write request with its read half or a
 * link PUT of several points. models_txn_begin() marks the undo log and
 * the journal queue (models_set_journal_marks); models_txn_rollback() puts
 * every model the operations since the mark changed back bit for bit,
 * except the live request/exception counters and last_error (the report
 * of the refusal, kept as it is), gives each of them a new instance (a
 * result cached for the undone change, keyed on instance and generation,
 * is never served for a later change reaching the same generation) and
 * drops the journal records queued since the mark;
 * models_txn_commit() keeps the changes (they stay in the batch being
 * gathered, undoable until the batch is durable). One transaction at a
 * time; not nested. Returns nothing: neither can fail. */
struct model_jmark {
    size_t len;
    int recs;
    uint64_t seq;
};
struct model_txn {
    size_t undo;              /* undo log length at begin */
    struct model_jmark jmark; /* journal queue position at begin */
    int active;
};
void models_txn_begin(struct model_txn *t);
void models_txn_commit(struct model_txn *t);
void models_txn_rollback(struct model_txn *t);

/* Journal queue positions for transactions (store_jmark/store_jrewind);
 * NULL: rollback leaves the journal queue alone. */
typedef struct model_jmark (*model_jmark_fn)(void);
typedef void (*model_jrewind_fn)(struct model_jmark m);
void models_set_journal_marks(model_jmark_fn mark, model_jrewind_fn rewind);

/* The last upload block (Modbus registers 40..51) of md, recorded in the
 * undo log like every change. 0, or IT2ND_ERR_NOMEM (nothing changed). */
int models_set_upload(struct model *md, const uint16_t regs[IT2N_REGMAP_REG_UPLOAD_END - IT2N_REGMAP_REG_UP_I]);

/* Tests and fuzzers, a model put back to a saved state: models_dup gives
 * a copy of md in an allocation of its own (free() it; its B-spline
 * pointers point into the copy); models_copy copies src's bytes over dst,
 * which must be of the same kind and storage (models_add with the same
 * sizes), and points dst's B-spline data at dst's own storage. */
struct model *models_dup(const struct model *md);
void models_copy(struct model *dst, const struct model *src);

/* Bytes held by the undo log now (tests, statistics). */
size_t models_undo_bytes(void);

/* Loop passes. The changes of a pass are in the undo log; at the end of
 * the pass (after the group commit) models_pass_end() either drops their
 * undo records (ok, the changes are durable: fn, if not NULL, is called
 * once per model whose state or generation moved, with the old values) or
 * puts every touched model back as it was (the commit failed, so nothing
 * acknowledged it). Request/exception counters are not rolled back. fn
 * may look at the model's header fields only (id, state, gen, last_op,
 * last_err, counters): when a later batch has already changed the model,
 * it is given a header-only copy as of the end of the batch. */
typedef void (*model_changed_fn)(void *arg, const struct model *md, int old_state, uint32_t old_gen);
void models_pass_end(int ok, model_changed_fn fn, void *arg);
/* True when a model was changed in the current pass (or is in a batch
 * being made durable). */
int models_pass_dirty(void);

/* Batches (the writer thread, docs/daemon.md "The writer thread"). The
 * changes of the loop passes since the last hand-off form the gathered
 * batch; models_batch_submit() makes it the in-flight batch when its WAL
 * records go to the writer thread (at most one in flight); after the
 * writer's fdatasync models_batch_done() either drops the in-flight copies
 * (ok: fn called per model whose state or generation moved with the batch,
 * with the state right after it) or, on failure, puts every model of the
 * in-flight and of the gathered batch back to its last durable state
 * (last_error IT2ND_ERR_IO): the gathered batch built on the failed one,
 * and its records are dropped with it. models_pass_end(ok) is submit +
 * done at once (no batch in flight: the synchronous paths).
 *
 * Readers see the last durable state: models_view(md) is md as it was
 * before the oldest batch that changed it and is not yet durable (md
 * itself when none); only its request/exception counters, last_error and
 * unit are live. Writes apply to md itself. The view is built from md and
 * the undo log when first asked for (into a buffer kept per model: no
 * allocation, cannot fail) and kept until a batch ends or a rollback; it
 * is valid until the next models_* call that may end a batch. */
void models_batch_submit(void);
void models_batch_done(int ok, model_changed_fn fn, void *arg);
struct model *models_view(struct model *md);

/* Apply a record (WAL replay): same as the operations, not journaled. */
int models_apply(const struct model_rec *rec, it2n_errinfo *err);

/* Entries present / required of the current configuration. */
unsigned models_present(const struct model *md);
unsigned models_required(const struct model *md);

/* The model whatever its kind: intervals (Bezier: degrees), flags, the
 * data points, and the core's queries on the solved model (same contracts
 * as it2n_eval, it2n_deriv, it2n_locate, it2n_sample and their
 * it2n_bspline_* twins). */
unsigned models_n(const struct model *md);
unsigned models_m(const struct model *md);
unsigned models_flags(const struct model *md);
unsigned models_missing(const struct model *md);
/* Is footprint fp of data point (i, j) stored? Its values (zeros if not). */
int models_point_present(const struct model *md, unsigned i, unsigned j, unsigned fp);
void models_point_get(const struct model *md, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT]);
/* The same in the fine layout (T, I, F in Q30, as stored). */
void models_point_get_fine(const struct model *md, unsigned i, unsigned j, unsigned fp, it2n_val vals[IT2N_CH_COUNT]);
/* Does the solved model carry footprint fp? */
int models_has_fp(const struct model *md, unsigned fp);
int models_eval(const struct model *md, it2n_par u, it2n_par w, it2n_point *out, it2n_errinfo *err);
int models_deriv(const struct model *md, it2n_par u, it2n_par w, it2n_point *du, it2n_point *dw, it2n_errinfo *err);
int models_locate(const struct model *md, it2n_val x, it2n_val y, it2n_locate_result *out, it2n_errinfo *err);
int models_sample(const struct model *md, unsigned rows, unsigned cols, it2n_sample_cb cb, void *ctx,
                  it2n_errinfo *err);
/* The solved model's net: rows x cols coefficients per footprint and
 * channel (Bezier: control points, (n+1) x (m+1); B-spline: (n+3) x (m+3)
 * B-spline coefficients), 0 x 0 while not solved. Coefficient (r, s) of
 * footprint fp, channel ch in Q24 (0 outside). */
unsigned models_net_rows(const struct model *md);
unsigned models_net_cols(const struct model *md);
it2n_val models_coef(const struct model *md, unsigned r, unsigned s, unsigned fp, unsigned ch);

#endif
