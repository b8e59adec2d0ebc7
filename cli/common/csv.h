/*
 * Streaming reader for the it2n dataset CSV format, shared by the CLI and the
 * daemon. No heap, never prints or exits: errors come back as structs and
 * cli_csv_message() turns one into text (the only libc use is snprintf).
 *
 * Format: '#' comment lines and blank lines anywhere; a header line
 *   i,j,footprint,x,y,T,I,F   or   i,j,footprint,x,y,z,T,I,F
 * then one row per grid point and footprint. Fields may be padded with
 * spaces or tabs; lines end in LF or CRLF. Degrees are n = max i, m = max j;
 * z is present iff the header has it; the model is type-1 iff every row is
 * footprint D, otherwise all seven footprints are required. Numbers are
 * read exactly rounded: coordinates to Q24, memberships T, I, F to Q30
 * (it2n_parse_memb; stored with it2n_dataset_put_fine, so a degree-7 net
 * is not moved by Q24 input rounding).
 *
 * Contract:
 *   cli_csv_init(p, flags);                     flags: extra IT2N_F_* (CHORD)
 *   cli_csv_feed(p, buf, len, &e) ...           any chunking, same result
 *   cli_csv_finish(p, &ds, &e);                 builds and checks ds
 * or, for the B-spline kind (grids up to 256 x 256, caller storage):
 *   cli_csv_init_bspline(p, scratch, lines);
 *   cli_csv_feed(p, buf, len, &e) ...
 *   cli_csv_finish_bspline(p, &bds, &e);        bds lives in scratch
 * The first error is sticky: later feeds and finish return it again. The
 * parser keeps the line of every (i, j, footprint) so errors found later
 * (it2n_model_solve, ...) can be mapped back with cli_csv_locate().
 */
#ifndef CLI_CSV_H
#define CLI_CSV_H

#include "it2n.h"

#include <stddef.h>
#include <stdint.h>

/* Longest accepted line, in bytes, without the line end. */
#define CLI_CSV_LINE_MAX 256

/* Reader errors; core errors (IT2N_ERR_*) are passed through unchanged. */
enum cli_csv_error_code {
    CLI_CSV_ERR_HEADER = -101,    /* header missing or not a known layout */
    CLI_CSV_ERR_FIELDS = -102,    /* wrong number of fields in a row      */
    CLI_CSV_ERR_NUMBER = -103,    /* field is not a decimal number        */
    CLI_CSV_ERR_INDEX = -104,     /* i or j not an integer in 0..MAX      */
    CLI_CSV_ERR_FOOTPRINT = -105, /* unknown footprint name               */
    CLI_CSV_ERR_LONG = -106,      /* line longer than CLI_CSV_LINE_MAX   */
    CLI_CSV_ERR_EMPTY = -107,     /* no data rows                         */
    CLI_CSV_ERR_DEGREE = -108,    /* max i or max j is 0 (degree < 1)     */
    CLI_CSV_ERR_BINARY = -109,    /* NUL or other control byte in a line  */
    CLI_CSV_ERR_QUOTE = -110,     /* a "quoted" field with '"' or ',' in it */
    CLI_CSV_ERR_SEPARATOR = -111  /* header separated by ';' or tab, not ',' */
};

/* What went wrong and where. line is 1-based, 0 when no row is to blame. */
typedef struct cli_csv_error {
    int code;            /* CLI_CSV_ERR_* or IT2N_ERR_*              */
    unsigned long line;  /* offending line, or 0                      */
    unsigned long other; /* first line of a duplicate, or 0           */
    int field;           /* 1-based field number, or 0                */
    int got, expected;   /* field count, or the control byte in got   */
    char text[40];       /* offending field text (truncated), or ""   */
    it2n_errinfo info;   /* core detail (code, i, j, fp, ch, ...)     */
    uint8_t bspline;     /* read for the B-spline kind (index limits) */
} cli_csv_error;

/* Storage of a B-spline read: scratch records and line numbers for the
 * largest grid, IT2N_BSPLINE_MAX_N + 1 points per side (type-2). */
#define CLI_CSV_BSPLINE_SIDE ((size_t)IT2N_BSPLINE_MAX_N + 1u)
#define CLI_CSV_BSPLINE_RECS IT2N_BSPLINE_DATA_RECS(IT2N_BSPLINE_MAX_N, IT2N_BSPLINE_MAX_N, 0u)
#define CLI_CSV_BSPLINE_LINES (CLI_CSV_BSPLINE_SIDE * CLI_CSV_BSPLINE_SIDE * IT2N_FP_COUNT)

/* Parser state; all memory is here (about 24 KiB). Treat as opaque. */
typedef struct cli_csv_reader {
    int error;                       /* sticky first error, or 0      */
    cli_csv_error err;               /* ... and its detail            */
    unsigned long line;              /* lines completed so far        */
    size_t len;                      /* bytes in buf                  */
    uint8_t overlong, cr, header, z; /* line state, header seen, z    */
    unsigned flags;                  /* extra IT2N_F_* from init      */
    unsigned rows, max_i, max_j;
    uint8_t non_d; /* a footprint other than D seen */
    char buf[CLI_CSV_LINE_MAX + 1];
    uint32_t lines[IT2N_DIM][IT2N_DIM][IT2N_FP_COUNT]; /* 0 = absent */
    /* Rows as read, validated by it2n_dataset_put on a maximal grid so
     * range errors are found (and named) on the line that has them. */
    it2n_dataset scratch;
    /* B-spline reads: the same in caller storage, for up to 256 x 256
     * points; line of (i, j, fp) at bs_lines[(i * SIDE + j) * 7 + fp]. */
    uint8_t bspline;
    uint32_t *bs_lines;
    it2n_bspline_data bs_scratch;
} cli_csv_reader;

/* Start reading; flags are extra IT2N_F_* bits for the data set (CHORD). */
void cli_csv_init(cli_csv_reader *p, unsigned flags);

/*
 * Start reading a data set for the B-spline kind: grid indices 0..
 * IT2N_BSPLINE_MAX_N, uniform parameters only. scratch holds
 * CLI_CSV_BSPLINE_RECS records, lines CLI_CSV_BSPLINE_LINES words (both
 * the caller's, about 15 MB and 1.8 MB at the default 255; the line
 * table is cleared here, the records need not be).
 */
void cli_csv_init_bspline(cli_csv_reader *p, it2n_bspline_rec *scratch, uint32_t *lines);

/*
 * End of a B-spline read: as cli_csv_finish, into *ds, whose records are
 * the scratch passed to cli_csv_init_bspline (compacted in place to the
 * file's grid). ds is only written on success.
 */
int cli_csv_finish_bspline(cli_csv_reader *p, it2n_bspline_data *ds, cli_csv_error *err);

/*
 * Consume len bytes (any split, even mid-line). Returns IT2N_OK or the first
 * error (also stored in *err when err is not NULL).
 */
int cli_csv_feed(cli_csv_reader *p, const char *data, size_t len, cli_csv_error *err);

/*
 * End of input: derive degrees, z and type-1, fill ds with
 * it2n_dataset_init/it2n_dataset_put in file order, then
 * it2n_dataset_check. Returns IT2N_OK or the first error with its line.
 * ds is only written on success.
 */
int cli_csv_finish(cli_csv_reader *p, it2n_dataset *ds, cli_csv_error *err);

/*
 * Turn a core error found after parsing (it2n_model_solve, ...) into a
 * reader error naming the line of (info->i, info->j, info->fp) if known.
 */
void cli_csv_locate(const cli_csv_reader *p, const it2n_errinfo *info, cli_csv_error *err);

/*
 * Describe err as "NAME:LINE: message" (NAME alone if no line) in buf, NUL
 * terminated, truncated to size. Returns the length snprintf would write.
 */
int cli_csv_message(const cli_csv_error *err, const char *name, char *buf, size_t size);

#endif /* CLI_CSV_H */
