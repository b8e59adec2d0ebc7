/*
 * Instruction counter of the benchmark images. qemu runs them with
 * `-icount shift=0`: virtual time advances exactly 1 ns per executed
 * instruction. The CMSDK APB timer 0 of the mps2 boards (0x40000000, 32-bit
 * down counter, clocked at the 25 MHz SYSCLK) thus counts one tick per 40
 * instructions; a reading is exact when the timer is read (qemu ends the
 * translation block at an I/O access). DWT CYCCNT reads as 0 on qemu 7.2.
 * bc_counter_validate() checks the whole chain on a loop of known length.
 */
#ifndef BENCH_COUNTER_H
#define BENCH_COUNTER_H

#include <stdint.h>

#define BC_TIMER0_VALUE (*(volatile uint32_t *)0x40000004u)
#define BC_INSTR_PER_TICK 40u /* 1e9 ns/s / 25 MHz, at 1 instruction per ns */

/* Start timer 0 free-running from 0xFFFFFFFF. */
void bc_counter_start(void);

static inline uint32_t bc_now(void)
{
    return BC_TIMER0_VALUE;
}

/* Instructions between two readings (the timer counts down). */
static inline uint64_t bc_instr(uint32_t t0, uint32_t t1)
{
    return (uint64_t)(uint32_t)(t0 - t1) * BC_INSTR_PER_TICK;
}

/* An assembly loop of exactly iters iterations of BC_LOOP_BODY instructions
 * (iters >= 1). */
#define BC_LOOP_BODY 4u
void bc_known_loop(uint32_t iters);

/* Measure bc_known_loop at two lengths: the difference must be
 * BC_LOOP_BODY * (difference of iterations) within 1 %. Fills expected and
 * measured instructions; returns 0 if within 1 %, else -1. */
int bc_counter_validate(uint64_t *expected, uint64_t *measured);

#endif /* BENCH_COUNTER_H */
