/*
 * fw_print: the firmware examples' output over semihosting, one line at a
 * time (firmware.c and survey.c print the same way; tests read the lines).
 * Text is collected in a static line buffer of FW_PRINT_LINE bytes (longer
 * text is cut) and written with a newline by fw_print_flush. No heap.
 */
#ifndef FW_PRINT_H
#define FW_PRINT_H

#include <stdint.h>

#include "it2n.h"

#ifndef FW_PRINT_LINE
#define FW_PRINT_LINE 1024u
#endif

/* Append s to the line. */
void fw_print_str(const char *s);

/* Append v in decimal. */
void fw_print_u64(uint64_t v);

/* Append v in decimal, '-' first when negative. */
void fw_print_i64(int64_t v);

/* One evaluation as the line tests/firmware compares with Modbus:
 *   EVAL <u x10000> <w x10000> <out_of_range> <42 values> <12 summary>
 * (raw Q24 integers; the summary in register order: upper_min, upper_max,
 * lower_min, lower_max), then flushed. */
void fw_print_eval(uint16_t ku, uint16_t kw, const it2n_point *p);

/* Write the line and a newline to the host's console; start a new line. */
void fw_print_flush(void);

#endif
