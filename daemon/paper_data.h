/* paper_data — the paper's 4x4 example data set (examples/paper_4x4.csv),
 * compiled into the daemon at build time (daemon/tools/csv2c.awk) so the
 * default configuration serves without any file. */
#ifndef IT2ND_PAPER_DATA_H
#define IT2ND_PAPER_DATA_H

#include <stddef.h>

struct paper_row {
    unsigned char i, j;
    const char *fp;
    const char *val[5]; /* x, y, T, I, F as decimal text from the CSV */
};

extern const struct paper_row paper_data_rows[];
extern const size_t paper_data_nrows;

#endif
