/*
 * Streaming dataset CSV reader (see csv.h for the format and contract).
 * Lines are collected in a fixed buffer; each complete line is parsed at
 * once, and each row is validated by the core on a scratch data set so
 * errors carry the line that caused them.
 */
#include "csv.h"

#include <stdio.h>
#include <string.h>

#define CLI_CSV_MAX_FIELDS 10

/* Sizes the code relies on. */
_Static_assert(CLI_CSV_LINE_MAX >= 64 && CLI_CSV_LINE_MAX < 65536, "line buffer");
_Static_assert(IT2N_MAX_DEGREE <= 999, "grid index fits the 3-digit parse");
_Static_assert(sizeof(((cli_csv_error *)0)->text) >= 16, "error text");

static const char hdr_xy[] = "i,j,footprint,x,y,T,I,F";
static const char hdr_xyz[] = "i,j,footprint,x,y,z,T,I,F";

typedef struct csv_field {
    const char *s;
    size_t len;
} csv_field;

static void set_text(cli_csv_error *e, const char *s, size_t len)
{
    if (len >= sizeof(e->text)) {
        len = sizeof(e->text) - 1u;
    }
    memcpy(e->text, s, len);
    e->text[len] = '\0';
}

static void err_clear(cli_csv_error *e)
{
    memset(e, 0, sizeof(*e));
    e->info.i = -1;
    e->info.j = -1;
    e->info.fp = -1;
    e->info.ch = -1;
}

/* Record the first error (sticky) and return its code. */
static int fail(cli_csv_reader *p, int code, int field, const csv_field *f)
{
    p->err.bspline = p->bspline;
    p->err.code = code;
    p->err.info.code = code;
    p->err.line = p->line;
    p->err.field = field;
    if (f != NULL) {
        set_text(&p->err, f->s, f->len);
    }
    p->error = code;
    return code;
}

static bool is_space(char c)
{
    return c == ' ' || c == '\t';
}

static csv_field trim(const char *s, size_t len)
{
    csv_field f;
    while (len > 0u && is_space(*s)) {
        s++;
        len--;
    }
    while (len > 0u && is_space(s[len - 1u])) {
        len--;
    }
    f.s = s;
    f.len = len;
    return f;
}

/* A field wrapped whole in double quotes (as spreadsheets export every
 * field) is unwrapped; none of ours can hold a ',' or '"', so a quote
 * anywhere else is refused rather than guessed at. False on a bad quote. */
static bool unquote(csv_field *f)
{
    size_t k;
    if (f->len >= 2u && f->s[0] == '"' && f->s[f->len - 1u] == '"') {
        *f = trim(f->s + 1, f->len - 2u);
    }
    for (k = 0; k < f->len; k++) {
        if (f->s[k] == '"') {
            return false;
        }
    }
    return true;
}

/* Split on ','; returns the field count (CLI_CSV_MAX_FIELDS + 1 if more), or
 * -(k + 1) when field k is badly quoted (out[k] is that field). */
static int split(const char *s, size_t len, csv_field *out)
{
    int n = 0;
    size_t start = 0, k;
    for (k = 0; k <= len; k++) {
        if (k == len || s[k] == ',') {
            if (n == CLI_CSV_MAX_FIELDS) {
                return CLI_CSV_MAX_FIELDS + 1;
            }
            out[n] = trim(s + start, k - start);
            if (!unquote(&out[n])) {
                out[n] = trim(s + start, k - start);
                return -(n + 1);
            }
            n++;
            start = k + 1u;
        }
    }
    return n;
}

/* A bad quote from split(): record it against field -n. */
static int fail_quote(cli_csv_reader *p, int n, const csv_field *f)
{
    return fail(p, CLI_CSV_ERR_QUOTE, -n, &f[-n - 1]);
}

static bool field_is(const csv_field *f, const char *name)
{
    return f->len == strlen(name) && memcmp(f->s, name, f->len) == 0;
}

static int parse_header(cli_csv_reader *p, const char *s, size_t len)
{
    csv_field f[CLI_CSV_MAX_FIELDS];
    static const char *const xy[] = {"i", "j", "footprint", "x", "y", "T", "I", "F"};
    static const char *const xyz[] = {"i", "j", "footprint", "x", "y", "z", "T", "I", "F"};
    const char *const *want = NULL;
    int n = split(s, len, f), k;
    csv_field whole;

    if (n < 0) {
        return fail_quote(p, n, f);
    }
    if (n == 1) {
        /* One field: a spreadsheet's ';' (or tab) separated export. */
        for (k = 0; (size_t)k < len; k++) {
            if (s[k] == ';' || s[k] == '\t') {
                fail(p, CLI_CSV_ERR_SEPARATOR, 0, NULL);
                p->err.got = s[k];
                return p->error;
            }
        }
    }
    if (n == 8) {
        want = xy;
    } else if (n == 9) {
        want = xyz;
    }
    for (k = 0; want != NULL && k < n; k++) {
        if (!field_is(&f[k], want[k])) {
            want = NULL;
        }
    }
    if (want == NULL) {
        whole = trim(s, len);
        return fail(p, CLI_CSV_ERR_HEADER, 0, &whole);
    }
    p->z = n == 9;
    p->header = 1;
    if (p->bspline) {
        /* The largest grid, records not cleared (15 MB): bs_lines says which
         * are set, and finish rebuilds every present flag from it. */
        p->bs_scratch.cap = CLI_CSV_BSPLINE_RECS;
        p->bs_scratch.n = IT2N_BSPLINE_MAX_N;
        p->bs_scratch.m = IT2N_BSPLINE_MAX_N;
        p->bs_scratch.flags = (uint8_t)(p->z ? IT2N_F_Z : 0u);
        return IT2N_OK;
    }
    it2n_dataset_init(&p->scratch, IT2N_MAX_DEGREE, IT2N_MAX_DEGREE, p->z ? IT2N_F_Z : 0u, NULL);
    return IT2N_OK;
}

/* A grid index: decimal digits only, value 0..max. */
static bool parse_index(const csv_field *f, unsigned max, unsigned *out)
{
    unsigned v = 0;
    size_t k;
    if (f->len == 0u || f->len > 3u) {
        return false;
    }
    for (k = 0; k < f->len; k++) {
        if (f->s[k] < '0' || f->s[k] > '9') {
            return false;
        }
        v = v * 10u + (unsigned)(f->s[k] - '0');
    }
    if (v > max) {
        return false;
    }
    *out = v;
    return true;
}

static int parse_row(cli_csv_reader *p, const char *s, size_t len)
{
    static const int8_t ch_xy[] = {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F};
    static const int8_t ch_xyz[] = {IT2N_CH_X, IT2N_CH_Y, IT2N_CH_Z, IT2N_CH_T, IT2N_CH_I, IT2N_CH_F};
    csv_field f[CLI_CSV_MAX_FIELDS];
    const int8_t *chs = p->z ? ch_xyz : ch_xy;
    int want = p->z ? 9 : 8;
    int n = split(s, len, f), k, rc, fp;
    unsigned i, j, max = p->bspline ? IT2N_BSPLINE_MAX_N : IT2N_MAX_DEGREE;
    uint32_t *line;
    it2n_val vals[IT2N_CH_COUNT];
    it2n_errinfo info;

    if (n < 0) {
        return fail_quote(p, n, f);
    }
    if (n != want) {
        fail(p, CLI_CSV_ERR_FIELDS, 0, NULL);
        p->err.got = n > CLI_CSV_MAX_FIELDS ? CLI_CSV_MAX_FIELDS + 1 : n;
        p->err.expected = want;
        return p->error;
    }
    if (!parse_index(&f[0], max, &i)) {
        return fail(p, CLI_CSV_ERR_INDEX, 1, &f[0]);
    }
    p->err.info.i = (int16_t)i;
    if (!parse_index(&f[1], max, &j)) {
        return fail(p, CLI_CSV_ERR_INDEX, 2, &f[1]);
    }
    p->err.info.j = (int16_t)j;
    fp = it2n_fp_from_name(f[2].s, f[2].len);
    if (fp < 0) {
        return fail(p, CLI_CSV_ERR_FOOTPRINT, 3, &f[2]);
    }
    p->err.info.fp = (int8_t)fp;

    memset(vals, 0, sizeof(vals));
    for (k = 3; k < want; k++) {
        int8_t ch = chs[k - 3];
        /* memberships at 2^-30 (it2n.h, IT2N_MEMB_FRAC): a degree-7 net
         * amplifies their rounding up to 4.4e4 times */
        rc = ch >= IT2N_CH_T ? it2n_parse_memb(f[k].s, f[k].len, &vals[ch])
                             : it2n_parse_val(f[k].s, f[k].len, &vals[ch]);
        if (rc != IT2N_OK) {
            p->err.info.ch = ch;
            if (rc == IT2N_ERR_RANGE) {
                p->err.info.lo = -(it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE;
                p->err.info.hi = (it2n_val)IT2N_COORD_LIMIT * IT2N_VAL_ONE;
                if (ch >= IT2N_CH_T) {
                    p->err.info.lo = 0;
                    p->err.info.hi = IT2N_VAL_ONE;
                }
                return fail(p, IT2N_ERR_RANGE, k + 1, &f[k]);
            }
            return fail(p, CLI_CSV_ERR_NUMBER, k + 1, &f[k]);
        }
    }

    line = p->bspline ? &p->bs_lines[((size_t)i * CLI_CSV_BSPLINE_SIDE + j) * IT2N_FP_COUNT + (unsigned)fp]
                      : &p->lines[i][j][fp];
    if (*line != 0u) {
        fail(p, IT2N_ERR_DUPLICATE, 0, NULL);
        p->err.other = *line;
        return p->error;
    }
    /* (duplicates were caught above: replace, the flags are not cleared) */
    rc = p->bspline ? it2n_bspline_data_put_fine(&p->bs_scratch, i, j, (unsigned)fp, vals, true, &info)
                    : it2n_dataset_put_fine(&p->scratch, i, j, (unsigned)fp, vals, false, &info);
    if (rc != IT2N_OK) {
        int field = 0;
        for (k = 3; k < want; k++) {
            if (info.ch >= 0 && chs[k - 3] == info.ch) {
                field = k + 1;
            }
        }
        fail(p, rc, field, field > 0 ? &f[field - 1] : NULL);
        p->err.info = info;
        return p->error;
    }
    /* Saturate: 0 means absent, and no real row lies 4 G lines down. */
    *line = p->line > UINT32_MAX ? UINT32_MAX : (uint32_t)p->line;
    p->rows++;
    p->max_i = i > p->max_i ? i : p->max_i;
    p->max_j = j > p->max_j ? j : p->max_j;
    if (fp != IT2N_FP_D) {
        p->non_d = 1;
    }
    return IT2N_OK;
}

static int parse_line(cli_csv_reader *p)
{
    const char *s = p->buf;
    size_t len = p->len, k;
    csv_field t;

    if (p->overlong) {
        return fail(p, CLI_CSV_ERR_LONG, 0, NULL);
    }
    if (p->line == 1u && len >= 3u && memcmp(s, "\xEF\xBB\xBF", 3) == 0) {
        s += 3; /* UTF-8 byte order mark */
        len -= 3u;
    }
    for (k = 0; k < len; k++) {
        unsigned char c = (unsigned char)s[k];
        if ((c < 0x20u && c != '\t') || c == 0x7Fu) {
            fail(p, CLI_CSV_ERR_BINARY, 0, NULL);
            p->err.got = c;
            return p->error;
        }
    }
    t = trim(s, len);
    if (t.len == 0u || t.s[0] == '#') {
        return IT2N_OK;
    }
    if (!p->header) {
        return parse_header(p, t.s, t.len);
    }
    err_clear(&p->err);
    return parse_row(p, t.s, t.len);
}

void cli_csv_init(cli_csv_reader *p, unsigned flags)
{
    memset(p, 0, sizeof(*p));
    err_clear(&p->err);
    p->flags = flags & IT2N_F_CHORD;
}

void cli_csv_init_bspline(cli_csv_reader *p, it2n_bspline_rec *scratch, uint32_t *lines)
{
    cli_csv_init(p, 0u);
    p->bspline = 1;
    p->err.bspline = 1;
    p->bs_lines = lines;
    memset(lines, 0, CLI_CSV_BSPLINE_LINES * sizeof(*lines));
    p->bs_scratch.rec = scratch;
}

static int report(const cli_csv_reader *p, cli_csv_error *err)
{
    if (err != NULL) {
        *err = p->err;
    }
    return p->error;
}

/* The core refused the finished data set (code rc): the error at the row
 * info names, kept as the reader's. */
static int refused(cli_csv_reader *p, const it2n_errinfo *info, int rc, cli_csv_error *err)
{
    cli_csv_locate(p, info, &p->err);
    p->err.code = rc;
    p->error = rc;
    return report(p, err);
}

int cli_csv_feed(cli_csv_reader *p, const char *data, size_t len, cli_csv_error *err)
{
    size_t k;
    for (k = 0; k < len && p->error == 0; k++) {
        char c = data[k];
        if (c == '\n') {
            p->line++;
            if (p->len > 0u && p->buf[p->len - 1u] == '\r') {
                p->len--;
            }
            if (p->len > CLI_CSV_LINE_MAX) {
                p->overlong = 1;
            }
            parse_line(p);
            p->len = 0;
            p->overlong = 0;
        } else if (p->len < CLI_CSV_LINE_MAX + 1u) {
            /* One extra byte so a CR before LF still fits a full line. */
            p->buf[p->len++] = c;
        } else {
            p->overlong = 1;
        }
    }
    return report(p, err);
}

void cli_csv_locate(const cli_csv_reader *p, const it2n_errinfo *info, cli_csv_error *err)
{
    err_clear(err);
    err->code = info->code;
    err->info = *info;
    err->bspline = p->bspline;
    if (p->bspline) {
        if (info->i >= 0 && info->j >= 0 && info->fp >= 0 && (size_t)info->i < CLI_CSV_BSPLINE_SIDE &&
            (size_t)info->j < CLI_CSV_BSPLINE_SIDE && info->fp < IT2N_FP_COUNT) {
            err->line = p->bs_lines[((size_t)info->i * CLI_CSV_BSPLINE_SIDE + (size_t)info->j) * IT2N_FP_COUNT +
                                    (size_t)info->fp];
            if (err->line != 0u && info->ch >= 0 && info->ch < IT2N_CH_COUNT) {
                err->field = 4 + info->ch - ((!p->z && info->ch > IT2N_CH_Z) ? 1 : 0);
            }
        }
        return;
    }
    if (info->i >= 0 && info->j >= 0 && info->fp >= 0 && info->i < IT2N_DIM && info->j < IT2N_DIM &&
        info->fp < IT2N_FP_COUNT) {
        err->line = p->lines[info->i][info->j][info->fp];
        if (err->line != 0u && info->ch >= 0 && info->ch < IT2N_CH_COUNT) {
            err->field = 4 + info->ch - ((!p->z && info->ch > IT2N_CH_Z) ? 1 : 0);
        }
    }
}

/* End of input checks shared by both kinds (bspline: the kind the caller
 * finishes, which must be the one the reader was set up for): IT2N_OK or
 * the error. */
static int finish_common(cli_csv_reader *p, bool bspline, cli_csv_error *err)
{
    if ((p->bspline != 0u) != bspline) {
        p->line = 0;
        fail(p, IT2N_ERR_INVAL, 0, NULL);
        return report(p, err);
    }
    if (p->error == 0 && (p->len > 0u || p->overlong)) {
        /* Last line without a line end. */
        cli_csv_feed(p, "\n", 1u, NULL);
    }
    if (p->error != 0) {
        return report(p, err);
    }
    if (!p->header) {
        p->line = 0;
        fail(p, CLI_CSV_ERR_HEADER, 0, NULL);
        return report(p, err);
    }
    if (p->rows == 0u) {
        p->line = 0;
        fail(p, CLI_CSV_ERR_EMPTY, 0, NULL);
        return report(p, err);
    }
    if (p->max_i == 0u || p->max_j == 0u) {
        p->line = 0;
        fail(p, CLI_CSV_ERR_DEGREE, 0, NULL);
        p->err.got = p->max_i == 0u ? 'i' : 'j';
        return report(p, err);
    }
    return IT2N_OK;
}

int cli_csv_finish_bspline(cli_csv_reader *p, it2n_bspline_data *ds, cli_csv_error *err)
{
    it2n_bspline_data out;
    it2n_errinfo info;
    unsigned flags, i, j, fp, nfp;
    size_t to = 0;
    int rc;

    rc = finish_common(p, true, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    flags = (p->z ? IT2N_F_Z : 0u) | (p->non_d ? 0u : IT2N_F_TYPE1);
    nfp = IT2N_BSPLINE_NFP(flags);
    /* Compact the scratch grid (stride SIDE, 7 footprints) in place to the
     * file's: every record moves to an index no larger than its own, so a
     * forward copy never overwrites a record still to be read. */
    for (i = 0; i <= p->max_i; i++) {
        for (j = 0; j <= p->max_j; j++) {
            size_t from = ((size_t)i * CLI_CSV_BSPLINE_SIDE + j) * IT2N_FP_COUNT;
            for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
                it2n_bspline_rec *r = &p->bs_scratch.rec[to];
                if (nfp == 1u && fp != IT2N_FP_D) {
                    continue;
                }
                if (p->bs_lines[from + fp] != 0u) {
                    *r = p->bs_scratch.rec[from + fp];
                    r->present = 1u;
                } else {
                    memset(r, 0, sizeof(*r));
                }
                to++;
            }
        }
    }
    out.rec = p->bs_scratch.rec;
    out.cap = CLI_CSV_BSPLINE_RECS;
    out.n = (uint16_t)p->max_i;
    out.m = (uint16_t)p->max_j;
    out.flags = (uint8_t)flags;
    /* the scratch is the data set now: no more rows */
    p->bs_scratch.n = 0;
    rc = it2n_bspline_data_check(&out, &info);
    if (rc != IT2N_OK) {
        return refused(p, &info, rc, err);
    }
    *ds = out;
    return IT2N_OK;
}

int cli_csv_finish(cli_csv_reader *p, it2n_dataset *ds, cli_csv_error *err)
{
    it2n_dataset out;
    it2n_errinfo info;
    unsigned flags, i, j, fp;
    int rc;

    rc = finish_common(p, false, err);
    if (rc != IT2N_OK) {
        return rc;
    }
    flags = p->flags | (p->z ? IT2N_F_Z : 0u) | (p->non_d ? 0u : IT2N_F_TYPE1);
    rc = it2n_dataset_init(&out, p->max_i, p->max_j, flags, &info);
    for (i = 0; rc == IT2N_OK && i <= p->max_i; i++) {
        for (j = 0; rc == IT2N_OK && j <= p->max_j; j++) {
            for (fp = 0; rc == IT2N_OK && fp < IT2N_FP_COUNT; fp++) {
                if (p->lines[i][j][fp] != 0u) {
                    it2n_val v[IT2N_CH_COUNT];
                    it2n_dataset_get_fine(&p->scratch, i, j, fp, v);
                    rc = it2n_dataset_put_fine(&out, i, j, fp, v, false, &info);
                }
            }
        }
    }
    if (rc == IT2N_OK) {
        rc = it2n_dataset_check(&out, &info);
    }
    if (rc != IT2N_OK) {
        return refused(p, &info, rc, err);
    }
    memcpy(ds, &out, sizeof(out));
    return IT2N_OK;
}

/* ---- Messages ----------------------------------------------------------- */

/* Q24 value as short decimal text: 6 decimals, trailing zeros dropped. */
static void short_val(char *buf, size_t size, it2n_val v)
{
    int n = it2n_format_val(buf, size, v, 6);
    if (n <= 0) {
        snprintf(buf, size, "?");
        return;
    }
    while (n > 1 && buf[n - 1] == '0') {
        buf[--n] = '\0';
    }
    if (n > 1 && buf[n - 1] == '.') {
        buf[--n] = '\0';
    }
}

/* " at (i=2,j=1,RL)" or "" */
static void where(char *buf, size_t size, const it2n_errinfo *info)
{
    const char *fpn = info->fp >= 0 ? it2n_fp_name((unsigned)info->fp) : NULL;
    if (info->i >= 0 && info->j >= 0 && fpn != NULL) {
        snprintf(buf, size, " at (i=%d,j=%d,%s)", info->i, info->j, fpn);
    } else if (info->i >= 0 && info->j >= 0) {
        snprintf(buf, size, " at (i=%d,j=%d)", info->i, info->j);
    } else {
        buf[0] = '\0';
    }
}

/* The message of a reader error (CLI_CSV_ERR_*) after pre ("FILE:LINE"),
 * or -1 when e->code is not one: the core's have their own. */
static int reader_message(const cli_csv_error *e, const char *pre, const char *chn, const char *at, char *buf,
                          size_t size)
{
    switch (e->code) {
    case CLI_CSV_ERR_HEADER:
        if (e->line == 0u) {
            return snprintf(buf, size, "%s: no header line (expected '%s' or '%s')", pre, hdr_xy, hdr_xyz);
        }
        return snprintf(buf, size, "%s: bad header '%s' (expected '%s' or '%s')", pre, e->text, hdr_xy, hdr_xyz);
    case CLI_CSV_ERR_FIELDS:
        return snprintf(buf, size, "%s: %s%d fields, expected %d (%s)", pre,
                        e->got > CLI_CSV_MAX_FIELDS ? "more than " : "",
                        e->got > CLI_CSV_MAX_FIELDS ? CLI_CSV_MAX_FIELDS : e->got, e->expected,
                        e->expected == 9 ? hdr_xyz : hdr_xy);
    case CLI_CSV_ERR_NUMBER: return snprintf(buf, size, "%s: %s='%s' is not a decimal number%s", pre, chn, e->text, at);
    case CLI_CSV_ERR_INDEX:
        if (e->bspline) {
            return snprintf(buf, size,
                            "%s: %s='%s' is not a grid index 0..%d "
                            "(IT2N_BSPLINE_MAX_N)",
                            pre, e->field == 1 ? "i" : "j", e->text, IT2N_BSPLINE_MAX_N);
        }
        return snprintf(buf, size,
                        "%s: %s='%s' is not a grid index 0..%d "
                        "(IT2N_MAX_DEGREE)",
                        pre, e->field == 1 ? "i" : "j", e->text, IT2N_MAX_DEGREE);
    case CLI_CSV_ERR_FOOTPRINT:
        return snprintf(buf, size,
                        "%s: unknown footprint '%s' (expected one of LL, LR, "
                        "L, D, R, RL, RR)",
                        pre, e->text);
    case CLI_CSV_ERR_LONG: return snprintf(buf, size, "%s: line longer than %d bytes", pre, CLI_CSV_LINE_MAX);
    case CLI_CSV_ERR_EMPTY: return snprintf(buf, size, "%s: no data rows after the header", pre);
    case CLI_CSV_ERR_DEGREE:
        if (e->bspline) {
            return snprintf(buf, size,
                            "%s: every row has %c=0: need 2 to %d grid points "
                            "per direction",
                            pre, e->got, IT2N_BSPLINE_MAX_N + 1);
        }
        return snprintf(buf, size,
                        "%s: every row has %c=0: need 2 to %d grid points "
                        "per direction (degree 1..%d)",
                        pre, e->got, IT2N_MAX_DEGREE + 1, IT2N_MAX_DEGREE);
    case CLI_CSV_ERR_QUOTE:
        return snprintf(buf, size,
                        "%s: field %d: bad quoting '%s' (a field may be "
                        "wrapped whole in \"...\", but never holds '\"' or ',')",
                        pre, e->field, e->text);
    case CLI_CSV_ERR_SEPARATOR:
        return snprintf(buf, size,
                        "%s: fields separated by %s, not ',' (save the CSV "
                        "with ',' as separator and '.' as decimal point; "
                        "expected '%s')",
                        pre, e->got == ';' ? "';'" : "tabs", hdr_xy);
    case CLI_CSV_ERR_BINARY: return snprintf(buf, size, "%s: control byte 0x%02x in line", pre, (unsigned)e->got);
    default: return -1;
    }
}

/* The message of a core error (IT2N_ERR_*, with its it2n_errinfo) after
 * pre. */
static int core_message(const cli_csv_error *e, const char *pre, const char *chn, const char *at, char *buf,
                        size_t size)
{
    char v[32], lo[32], hi[32], txt[48];
    const it2n_errinfo *info = &e->info;

    short_val(v, sizeof(v), info->value);
    short_val(lo, sizeof(lo), info->lo);
    short_val(hi, sizeof(hi), info->hi);
    snprintf(txt, sizeof(txt), "%s", e->text[0] != '\0' ? e->text : v);

    switch (e->code) {
    case IT2N_ERR_RANGE: return snprintf(buf, size, "%s: %s=%s outside [%s,%s]%s", pre, chn, txt, lo, hi, at);
    case IT2N_ERR_DUPLICATE:
        if (e->other != 0u) {
            return snprintf(buf, size, "%s: duplicate row%s (first on line %lu)", pre, at, e->other);
        }
        return snprintf(buf, size, "%s: duplicate row%s", pre, at);
    case IT2N_ERR_MISSING:
        return snprintf(buf, size, "%s: missing row%s%s", pre, at,
                        info->fp >= 0 && info->fp != IT2N_FP_D ? " (rows other than D are present, so every "
                                                                 "grid point needs all seven footprints)"
                                                               : "");
    case IT2N_ERR_ORDER: {
        /* The core reports value = v and lo = the previous footprint's. */
        const char *prev = info->fp > 0 ? it2n_fp_name((unsigned)info->fp - 1u) : NULL;
        return snprintf(buf, size,
                        "%s: %s=%s below %s's %s=%s: footprints must nest "
                        "LL<=LR<=L<=D<=R<=RL<=RR%s",
                        pre, chn, v, prev != NULL ? prev : "previous", chn, lo, at);
    }
    case IT2N_ERR_DEGENERATE: {
        /* i (u direction) or j (w direction) names the parameter that
         * coincides with its predecessor; neither when all points do. */
        bool wdir = info->j >= 0 || (info->i < 0 && info->value != 0);
        int k = wdir ? info->j : info->i;
        char which[48] = "every line of data points has zero length";
        if (k >= 0) {
            snprintf(which, sizeof(which), "parameters %d and %d coincide", k - 1, k);
        }
        return snprintf(buf, size,
                        "%s: degenerate chord-length parameterisation in the "
                        "%s direction: %s (drop --chord for uniform)",
                        pre, wdir ? "w (j)" : "u (i)", which);
    }
    default:
        if (info->ch >= 0) {
            return snprintf(buf, size, "%s: %s (%s)%s", pre, it2n_strerror(e->code), chn, at);
        }
        return snprintf(buf, size, "%s: %s%s", pre, it2n_strerror(e->code), at);
    }
}

int cli_csv_message(const cli_csv_error *e, const char *name, char *buf, size_t size)
{
    char pre[256], at[48];
    const it2n_errinfo *info = &e->info;
    const char *chn = info->ch >= 0 ? it2n_ch_name((unsigned)info->ch) : NULL;
    int n;

    if (chn == NULL) {
        chn = "value";
    }
    if (e->line != 0u) {
        snprintf(pre, sizeof(pre), "%s:%lu", name, e->line);
    } else {
        snprintf(pre, sizeof(pre), "%s", name);
    }
    where(at, sizeof(at), info);
    n = reader_message(e, pre, chn, at, buf, size);
    return n >= 0 ? n : core_message(e, pre, chn, at, buf, size);
}
