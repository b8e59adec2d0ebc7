/* Fuzz target "store": arbitrary bytes as the WAL and snapshot files of the
 * state directory, then store_open() recovery into a configured model
 * table (model 1: the paper's data, solved; 2: type-1 2x2, empty; 3: the
 * B-spline kind, 4x3 type-2, solved, so the baseline snapshot is version
 * 3 and WAL CONFIG records of it carry the kind byte; 4: chord with z,
 * 3x2, one point).
 *
 * Input: byte 0 selects how the rest becomes files (so the fuzzer gets
 * past the CRCs as well as attacking them):
 *   0  rest = the WAL file verbatim, no snapshot
 *   1  rest = WAL records the harness frames with valid length/CRC/seq:
 *      [type | 0x80 corrupt CRC][payload length][payload...]...
 *   2  a valid snapshot (written by store_snapshot at start-up) patched:
 *      [count][offset u24, xor]... [fix CRC: bit 0], then framed records
 *   3  rest = the snapshot file verbatim, no WAL
 *   4  a legacy version 1 snapshot (raw struct dump of it2nd 0.1, built
 *      here from the configured models) patched as in 2, then records
 *   5..7 as 1..3
 * Invariants: store_open succeeds, or refuses (a damaged WAL header or
 * snapshot, kept aside as NAME.damaged-<time>; a WAL that does not
 * continue the snapshot; a snapshot this build cannot read) keeping every
 * byte of both files, under their names or the kept ones, and refuses
 * again at the next start (issue 8 items 4, 5); when it succeeds: every
 * model has a valid header; a SOLVED model's data set passes
 * it2n_dataset_check, the model's degrees and flags are the data set's, and
 * its control nets (exponents and mantissas) are bit-identical to a fresh
 * it2n_model_solve of it (never serve wrong data); recovering the same
 * directory again gives the same models; the recovered models accept a
 * COMMIT through the WAL; nothing cut off the WAL (wal.cut-*) holds a
 * valid record later than the recovered state (that would be damage
 * inside the log served as complete, issue 20 item 3). (Found here and
 * fixed: the legacy version 1 loader served stored control nets;
 * corpus/store/v1_tampered_ctrl.) */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fake_env.h"
#include "fuzz_model_check.h"
#include "fuzz_tmp.h"
#include "it2n.h"
#include "it2n_proto.h"
#include "le_bytes.h"
#include "models.h"
#include "store.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define NMODELS 4
static char dir[128], wal_path[160], snap_path[160];
static uint8_t *snap_base;
static size_t snap_len;
static int snap_crc_fixable;

struct saved {
    int state;
    uint32_t gen;
    it2n_dataset ds;
    it2n_model mdl;
    struct model *copy; /* models_dup: the B-spline data and model */
};
static struct saved first[NMODELS];

static struct model *configured[NMODELS]; /* the table as configured, copied in */

static void setup_models(void)
{
    if (configured[0]) {
        /* Same as below without re-solving the paper model each time. */
        fuzz_check(models_init(8) == 0, "models_init");
        for (int k = 0; k < NMODELS; k++) {
            const struct model *c = configured[k];
            struct model *md = c->kind == MODEL_BSPLINE
                                   ? models_add(c->id, c->unit, MODEL_BSPLINE, c->cap_n, c->cap_m, 0)
                                   : models_add(c->id, c->unit, MODEL_BEZIER, c->ds.n, c->ds.m, c->ds.flags);
            fuzz_check(md != NULL, "models_add");
            models_copy(md, c);
        }
        models_set_journal(NULL, NULL);
        return;
    }
    static const it2n_val pt[IT2N_CH_COUNT] = { 0, 0, 0, IT2N_VAL_ONE / 2, IT2N_VAL_ONE / 4, IT2N_VAL_ONE / 8 };
    it2n_errinfo err;
    fuzz_standard_models(8);
    struct model *c = models_add(4, 4, MODEL_BEZIER, 3, 2, IT2N_F_CHORD | IT2N_F_Z);
    fuzz_check(c != NULL, "model 4");
    models_set_journal(NULL, NULL);
    fuzz_check(models_put(c, 0, 0, IT2N_FP_D, pt, false, &err) == IT2N_OK, "model 4 point");
    models_pass_end(1, NULL, NULL);
}

static void clear_dir(void)
{
    static const char *const names[] = { "wal", "wal.tmp", "snapshot", "snapshot.tmp" };
    char p[400];
    DIR *d;
    for (size_t k = 0; k < sizeof names / sizeof names[0]; k++) {
        snprintf(p, sizeof p, "%s/%s", dir, names[k]);
        unlink(p);
    }
    /* Files kept aside by a refused start, and WAL tails kept when cut. */
    if ((d = opendir(dir)) != NULL) {
        const struct dirent *e;
        while ((e = readdir(d)) != NULL)
            if (strstr(e->d_name, ".damaged-") || strstr(e->d_name, ".cut-")) {
                snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
                unlink(p);
            }
        closedir(d);
    }
}

/* A file's bytes, or NULL when it does not exist. */
static uint8_t *read_opt(const char *p, size_t *len)
{
    FILE *f = fopen(p, "rb");
    uint8_t *buf;
    long n;
    *len = 0;
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    rewind(f);
    buf = malloc((size_t)n + 1);
    fuzz_check(buf && fread(buf, 1, (size_t)n, f) == (size_t)n, "read a state file");
    fclose(f);
    *len = (size_t)n;
    return buf;
}

/* The bytes given as NAME are still there: under NAME or a kept name. */
static int kept_intact(const char *name, const uint8_t *want, size_t len)
{
    char p[400], prefix[32];
    size_t glen;
    int found = 0;
    DIR *d;
    if (!want)
        return 1;
    snprintf(p, sizeof p, "%s/%s", dir, name);
    uint8_t *got = read_opt(p, &glen);
    found = got && glen == len && memcmp(got, want, len) == 0;
    free(got);
    snprintf(prefix, sizeof prefix, "%s.damaged-", name);
    if (!found && (d = opendir(dir)) != NULL) {
        const struct dirent *e;
        while (!found && (e = readdir(d)) != NULL)
            if (!strncmp(e->d_name, prefix, strlen(prefix))) {
                snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
                got = read_opt(p, &glen);
                found = got && glen == len && memcmp(got, want, len) == 0;
                free(got);
            }
        closedir(d);
    }
    return found;
}

static uint8_t *slurp(const char *p, size_t *len)
{
    FILE *f = fopen(p, "rb");
    uint8_t *buf;
    long n;
    fuzz_check(f != NULL, "open baseline file");
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    rewind(f);
    buf = malloc((size_t)n + 1);
    fuzz_check(buf && fread(buf, 1, (size_t)n, f) == (size_t)n, "read baseline file");
    fclose(f);
    *len = (size_t)n;
    return buf;
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    snprintf(dir, sizeof dir, "%s/state", fuzz_tmp());
    snprintf(wal_path, sizeof wal_path, "%s/wal", dir);
    snprintf(snap_path, sizeof snap_path, "%s/snapshot", dir);
    /* The baseline snapshot comes from the daemon's own writer, so this
     * harness follows format changes. */
    clear_dir();
    setup_models();
    fuzz_check(store_open(dir, 0) == 0, "baseline store_open");
    fuzz_check(store_snapshot() == 0, "baseline snapshot");
    store_close();
    models_free();
    snap_base = slurp(snap_path, &snap_len);
    setup_models();
    for (int k = 0; k < NMODELS; k++) {
        configured[k] = models_dup(models_at(k));
        fuzz_check(configured[k] != NULL, "malloc");
    }
    models_free();
    snap_crc_fixable = snap_len > 4 && it2n_crc32c(snap_base, snap_len - 4) == le_get32(snap_base + snap_len - 4);
    return 0;
}

/* Frame records from d (see the header comment) into a WAL file image. */
static size_t frame_wal(const uint8_t *d, size_t n, uint8_t *out, size_t cap)
{
    size_t o = 16, pos = 0;
    uint64_t seq = 1;
    memset(out, 0, 16);
    memcpy(out, "IT2NWAL", 8);
    le_put32(out + 8, 1);
    while (pos + 2 <= n) {
        uint8_t t = d[pos], plen = d[pos + 1];
        pos += 2;
        if (plen > n - pos)
            plen = (uint8_t)(n - pos);
        if (o + 17 + plen > cap)
            break;
        le_put32(out + o, 9u + plen);
        for (int k = 0; k < 8; k++)
            out[o + 8 + (size_t)k] = (uint8_t)(seq >> (8 * k));
        out[o + 16] = t & 0x7Fu;
        memcpy(out + o + 17, d + pos, plen);
        le_put32(out + o + 4, it2n_crc32c(out + o + 8, 9u + plen) ^ (t & 0x80u ? 1u : 0u));
        o += 17 + plen;
        pos += plen;
        seq++;
    }
    return o;
}


/* Legacy version 1 snapshot: header, raw records, CRC-32C (frozen format
 * and core v1 model layout, see daemon/store.h). The model part holds what
 * it2nd 0.1 wrote there (data, control nets in Q24, solved); the loader
 * must ignore it and solve the data again. */
static uint8_t *build_v1(size_t *len)
{
    /* version 1 had Bezier models only: the B-spline one is left out */
    size_t n = 32 + (NMODELS - 1) * sizeof(struct store_v1_snap_model) + 4;
    size_t at = 0;
    uint8_t *b = calloc(1, n);
    fuzz_check(b != NULL, "v1 buffer");
    memcpy(b, "IT2NSNP", 8);
    le_put32(b + 8, 1);
    le_put32(b + 12, store_v1_layout_tag());
    le_put32(b + 24, NMODELS - 1);
    for (int k = 0; k < NMODELS; k++) {
        static struct store_v1_snap_model sm;
        const struct model *md = configured[k];
        if (md->kind != MODEL_BEZIER)
            continue;
        memset(&sm, 0, sizeof sm);
        sm.id = md->id;
        sm.state = md->state;
        sm.gen = md->gen;
        sm.points_rx = md->points_rx;
        sm.solves = md->solves;
        memcpy(sm.upload, md->mb.upload, sizeof sm.upload);
        store_v1_dataset_from(&sm.ds, &md->ds);
        sm.mdl.data = sm.ds;
        sm.mdl.generation = md->mdl.generation;
        sm.mdl.solved = md->mdl.solved;
        for (unsigned i = 0; i < IT2N_DIM; i++)
            for (unsigned j = 0; j < IT2N_DIM; j++)
                for (unsigned fp = 0; fp < IT2N_FP_COUNT; fp++)
                    for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++)
                        sm.mdl.ctrl[i][j][fp][ch] = it2n_model_ctrl(&md->mdl, i, j, fp, ch);
        memcpy(b + 32 + at++ * sizeof sm, &sm, sizeof sm);
    }
    le_put32(b + n - 4, it2n_crc32c(b, n - 4));
    *len = n;
    return b;
}

static void check_models(void)
{
    fuzz_check(models_count() == NMODELS, "model table size");
    for (int k = 0; k < NMODELS; k++) {
        const struct model *md = models_at(k);
        fuzz_check_model(md);
    }
}

static void write_files(const uint8_t *data, size_t size)
{
    static uint8_t img[1 << 16];
    static uint8_t *snap, *v1;
    static size_t v1_len;
    const uint8_t *d = data + 1;
    size_t n = size - 1;
    unsigned mode = data[0] & 7u;
    if (!v1)
        v1 = build_v1(&v1_len);
    if (mode > 4)
        mode -= 4;
    switch (mode) {
    case 0:
        fuzz_write_file(wal_path, d, n);
        break;
    case 1:
        fuzz_write_file(wal_path, img, frame_wal(d, n, img, sizeof img));
        break;
    case 2:
    case 4: {
        const uint8_t *base = mode == 2 ? snap_base : v1;
        size_t pos = 0, count = n ? d[pos++] : 0, slen = mode == 2 ? snap_len : v1_len;
        free(snap);
        snap = malloc(slen);
        fuzz_check(snap != NULL, "snapshot buffer");
        memcpy(snap, base, slen);
        for (size_t k = 0; k < count && pos + 4 <= n; k++, pos += 4) {
            size_t off = ((size_t)d[pos] | (size_t)d[pos + 1] << 8 | (size_t)d[pos + 2] << 16) % slen;
            snap[off] ^= d[pos + 3];
        }
        if (pos < n && (d[pos++] & 1u) && (mode == 4 || snap_crc_fixable)) {
            le_put32(snap + slen - 4, it2n_crc32c(snap, slen - 4));
        }
        fuzz_write_file(snap_path, snap, slen);
        fuzz_write_file(wal_path, img, frame_wal(d + pos, n - pos, img, sizeof img));
        break;
    }
    default:
        fuzz_write_file(snap_path, d, n);
        break;
    }
}

/* A record store.c would replay at p (n bytes): length, CRC, a payload
 * length its type allows; *rseq its seq. */
static int valid_rec(const uint8_t *p, size_t n, uint64_t *rseq)
{
    if (n < 17)
        return 0;
    uint32_t len = le_get32(p);
    if (len < 11 || len > 9u + 128u || 8u + len > n || le_get32(p + 4) != it2n_crc32c(p + 8, len))
        return 0;
    size_t pl = len - 9;
    int t = p[16];
    if (!((t == 1 && (pl == 5 || (pl == 6 && p[17 + 5] == 1))) || (t == 2 && pl == 5 + 8 * IT2N_CH_COUNT) || ((t == 3 || t == 4) && pl == 2)))
        return 0;
    *rseq = le_get64(p + 8);
    return 1;
}

/* After a successful recovery: the last seq it holds (the snapshot's, or
 * the WAL's last record), and no wal.cut-* with a valid record after it. */
static void check_cuts(void)
{
    size_t wl = 0, sl = 0, cl;
    uint8_t *w = read_opt(wal_path, &wl), *sn = read_opt(snap_path, &sl);
    uint64_t last = sn && sl >= 24 ? le_get64(sn + 16) : 0, rs;
    char p[400];
    DIR *d;
    for (size_t o = 16; w && o < wl;) {
        fuzz_check(valid_rec(w + o, wl - o, &rs), "the recovered WAL is valid to its end");
        if (rs > last)
            last = rs;
        o += 8u + le_get32(w + o);
    }
    if ((d = opendir(dir)) != NULL) {
        const struct dirent *e;
        while ((e = readdir(d)) != NULL) {
            if (!strstr(e->d_name, "wal.cut-"))
                continue;
            snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
            uint8_t *c = read_opt(p, &cl);
            for (size_t o = 0; c && o < cl; o++)
                if (valid_rec(c + o, cl - o, &rs)) {
                    fuzz_note("cut %s: valid record seq %llu at offset %zu, recovered up to %llu", e->d_name,
                              (unsigned long long)rs, o, (unsigned long long)last);
                    fuzz_check(rs <= last, "nothing valid behind the damage is cut off silently");
                }
            free(c);
        }
        closedir(d);
    }
    free(w);
    free(sn);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    it2n_errinfo err;
    if (size < 1 || size > 60000)
        return 0;
    clear_dir();
    write_files(data, size);
    size_t wlen, slen;
    uint8_t *wal0 = read_opt(wal_path, &wlen), *snap0 = read_opt(snap_path, &slen);

    /* First recovery. */
    setup_models();
    if (store_open(dir, 0) != 0) {
        /* Refused: nothing of what it was given may be lost, and the next
         * start must refuse too (never start empty over the evidence). */
        fuzz_check(kept_intact("wal", wal0, wlen) && kept_intact("snapshot", snap0, slen),
                   "a refused start keeps every byte of the WAL and the snapshot");
        models_free();
        setup_models();
        fuzz_check(store_open(dir, 0) != 0, "a refused start refuses again");
        fuzz_check(kept_intact("wal", wal0, wlen) && kept_intact("snapshot", snap0, slen),
                   "a second refused start keeps every byte too");
        models_free();
        free(wal0);
        free(snap0);
        (void)fake_log_errors();
        return 0;
    }
    free(wal0);
    free(snap0);
    check_models();
    check_cuts();
    for (int k = 0; k < NMODELS; k++) {
        const struct model *md = models_at(k);
        first[k].state = md->state;
        first[k].gen = md->gen;
        first[k].ds = md->ds;
        first[k].mdl = md->mdl;
        free(first[k].copy);
        first[k].copy = models_dup(md);
    }
    store_close();
    models_free();

    /* Second recovery of what the first one left: the same models. */
    setup_models();
    fuzz_check(store_open(dir, 0) == 0, "store_open again");
    for (int k = 0; k < NMODELS; k++) {
        const struct model *md = models_at(k);
        fuzz_note("model %d: state %d/%d gen %u/%u", md->id, first[k].state, md->state, first[k].gen, md->gen);
        fuzz_check(first[k].state == md->state && first[k].gen == md->gen &&
                       memcmp(&first[k].ds, &md->ds, sizeof md->ds) == 0 &&
                       memcmp(&first[k].mdl, &md->mdl, sizeof md->mdl) == 0 &&
                       fuzz_bs_same(first[k].copy, md),
                   "recovering twice gives the same models");
    }
    /* The recovered table keeps working: COMMIT each complete model
     * through the WAL (a failing solve is an answer, not a crash). */
    models_set_journal(store_append, NULL);
    models_set_journal_marks(store_jmark, store_jrewind);
    for (int k = 0; k < NMODELS; k++)
        (void)models_commit(models_at(k), &err);
    fuzz_check(store_commit() == 0, "WAL append after recovery");
    models_set_journal(NULL, NULL);
    store_close();
    models_free();
    (void)fake_log_errors();
    return 0;
}
