/* models — the model table: per model id a staging data set and a solved
 * it2n_model. Points PUT before the model is complete go to the data set;
 * completion or COMMIT solves with it2n_model_solve; PUTs into a solved
 * model use it2n_model_update (data set and model change together). Every
 * accepted change is reported to the journal hook (the WAL) before the
 * caller acknowledges it; a rejected change leaves the model exactly as it
 * was. */
#ifndef IT2ND_MODELS_H
#define IT2ND_MODELS_H

#include <stdint.h>

#include "it2n.h"
#include "it2n_regmap.h"

struct model {
    int id, unit;
    uint32_t instance;         /* unique per models_add and rollback (cache keys) */
    it2n_dataset ds;           /* current data (staging and solved)   */
    it2n_model mdl;            /* valid when state == IT2N_RS_SOLVED  */
    int state;                 /* enum it2n_regmap_state              */
    uint32_t gen;              /* bumped on every solve and update    */
    it2n_errinfo last_err;     /* code 0 = none                       */
    int last_op;               /* enum model_op of the last change     */
    uint32_t points_rx, solves, requests, exceptions;
    uint16_t upload[IT2N_REG_UPLOAD_END - IT2N_REG_UP_I]; /* last upload */
    /* Sample grid cache (D footprint T, I, F, Q24), valid for grid_gen and
     * the grid size it was computed for. */
    it2n_val grid[IT2N_REGMAP_GRID_MAX_NODES][3];
    uint32_t grid_gen;
    unsigned grid_rows, grid_cols;
    int grid_valid;
};

/* Journal record kinds (also the WAL record types). */
enum model_op { MOP_CONFIG = 1, MOP_POINT = 2, MOP_COMMIT = 3, MOP_CLEAR = 4 };

struct model_rec {
    int op;
    int id;
    unsigned n, m, flags;              /* MOP_CONFIG */
    unsigned i, j, fp;                 /* MOP_POINT  */
    it2n_val vals[IT2N_CH_COUNT];      /* MOP_POINT  */
    bool replace;                      /* MOP_POINT  */
};

/* Called for every accepted change; a non-zero return (a negative
 * IT2ND_ERR_* code, errs.h) rejects it (e.g. the WAL cannot take it), in
 * which case the model is rolled back and its last_error set to the code. */
typedef int (*model_journal_fn)(void *arg, const struct model_rec *rec);

/* Create the table with room for max models. Returns 0 or -1. */
int models_init(int max);
void models_free(void);
void models_set_journal(model_journal_fn fn, void *arg);

/* Add a model (id unique, unit unique). Returns it, or NULL. */
struct model *models_add(int id, int unit, unsigned n, unsigned m, unsigned flags);
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
/* replace false: an entry already present fails with IT2N_ERR_DUPLICATE. */
int models_put(struct model *md, unsigned i, unsigned j, unsigned fp,
               const it2n_val vals[IT2N_CH_COUNT], bool replace, it2n_errinfo *err);
int models_commit(struct model *md, it2n_errinfo *err);
int models_clear(struct model *md);

/* Loop passes. The first change of a model in a pass keeps a copy of it;
 * at the end of the pass (after the group commit) models_pass_end() either
 * drops the copies (ok, the changes are durable: fn, if not NULL, is called
 * once per model whose state or generation moved, with the old values) or
 * puts every touched model back as it was (the commit failed, so nothing
 * acknowledged it). Request/exception counters are not rolled back. */
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
 * unit are live. Writes apply to md itself. The view is valid until the
 * next models_* call that may end a batch. */
void models_batch_submit(void);
void models_batch_done(int ok, model_changed_fn fn, void *arg);
struct model *models_view(struct model *md);

/* Apply a record (WAL replay): same as the operations, not journaled. */
int models_apply(const struct model_rec *rec, it2n_errinfo *err);

/* Entries present / required of the current configuration. */
unsigned models_present(const struct model *md);
unsigned models_required(const struct model *md);

/* Refresh the sample grid cache if the generation moved. Returns 0 or an
 * it2n error code. */
int models_grid(struct model *md, unsigned rows, unsigned cols);

#endif
