/*
 * fw_print: lines over semihosting for the firmware examples (fw_print.h).
 */
#include "fw_print.h"

#include <stddef.h>

#include "semihost.h"

static char line[FW_PRINT_LINE];
static size_t line_len;

void fw_print_str(const char *s)
{
    while (*s != '\0' && line_len < sizeof line - 2u)
        line[line_len++] = *s++;
}

void fw_print_u64(uint64_t v)
{
    char b[24];
    unsigned n = sizeof b - 1u;
    b[n] = '\0';
    do {
        b[--n] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && n > 0u);
    fw_print_str(&b[n]);
}

void fw_print_i64(int64_t v)
{
    if (v < 0) {
        fw_print_str("-");
        fw_print_u64((uint64_t)0 - (uint64_t)v);
    } else {
        fw_print_u64((uint64_t)v);
    }
}

void fw_print_flush(void)
{
    line[line_len++] = '\n';
    line[line_len] = '\0';
    it2n_sh_write0(line);
    line_len = 0;
}

void fw_print_eval(uint16_t ku, uint16_t kw, const it2n_point *p)
{
    unsigned fp, ch, k;
    fw_print_str("EVAL ");
    fw_print_u64(ku);
    fw_print_str(" ");
    fw_print_u64(kw);
    fw_print_str(" ");
    fw_print_u64(p->out_of_range);
    for (fp = 0; fp < IT2N_FP_COUNT; fp++)
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            fw_print_str(" ");
            fw_print_i64(p->v[fp][ch]);
        }
    for (k = 0; k < 3; k++) {
        fw_print_str(" ");
        fw_print_i64(p->sum.upper_min[k]);
    }
    for (k = 0; k < 3; k++) {
        fw_print_str(" ");
        fw_print_i64(p->sum.upper_max[k]);
    }
    for (k = 0; k < 3; k++) {
        fw_print_str(" ");
        fw_print_i64(p->sum.lower_min[k]);
    }
    for (k = 0; k < 3; k++) {
        fw_print_str(" ");
        fw_print_i64(p->sum.lower_max[k]);
    }
    fw_print_flush();
}
