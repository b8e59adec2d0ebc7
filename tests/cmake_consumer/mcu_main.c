/* Cortex-M0+ side of the out-of-tree consumer: a freestanding image (no C
 * library start-up, no stdio) with a two-word vector table and a reset
 * handler that solves the paper model and leaves the results in RAM.
 * Linked, not run: make test checks its symbols (no heap, no float). */
#include <stddef.h>
#include <stdint.h>

#include "it2n.h"
#include "it2n_proto.h"
#include "paper_model.h"

/* The library's IT2N_CONFIG (tests/cmake_consumer/it2n_m0p_config.h) came
 * with find_package(it2n): this file names no option itself. (make test
 * also builds it without, to see the link-time ABI guard refuse it.) */
#ifndef CONSUMER_NO_CONFIG_CHECK /* make test: the link-time guard alone */
typedef char check_config_travelled[IT2N_MAX_DEGREE == 3 && !IT2N_CHORD ? 1 : -1];
#endif

/* What a debugger would read: status, D's T, I, F at (0.25, 0.75), CRC. */
volatile int32_t consumer_status;
volatile int64_t consumer_tif[3];
volatile uint32_t consumer_crc;

/* From m0p.ld. */
extern uint32_t consumer_stack_top[], consumer_bss_start[], consumer_bss_end[];
void consumer_reset(void);

struct consumer_vectors {
    uint32_t *initial_sp;
    void (*reset)(void);
};
__attribute__((section(".vectors"), used))
const struct consumer_vectors consumer_vector_table = {consumer_stack_top, consumer_reset};

void consumer_reset(void)
{
    it2n_errinfo err;
    it2n_val v[IT2N_CH_COUNT];
    int rc;
    size_t bss_words = (size_t)((uintptr_t)consumer_bss_end - (uintptr_t)consumer_bss_start) / 4u;
    for (size_t k = 0; k < bss_words; k++) {
        consumer_bss_start[k] = 0; /* no C start-up: clear .bss here */
    }
    consumer_crc = it2n_crc32c((const uint8_t *)"123456789", 9);
    rc = paper_model_solve(&err);
    if (rc == IT2N_OK) {
        rc = paper_model_eval(IT2N_PAR_ONE / 4, 3 * (IT2N_PAR_ONE / 4), v, &err);
    }
    if (rc == IT2N_OK) {
        consumer_tif[0] = v[IT2N_CH_T];
        consumer_tif[1] = v[IT2N_CH_I];
        consumer_tif[2] = v[IT2N_CH_F];
    }
    consumer_status = rc;
    for (;;) {
    }
}
