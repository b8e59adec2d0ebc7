/*
 * Stack high-water mark of one call, by painting: fill the free stack below
 * the caller's SP with a pattern, call, find the lowest overwritten word.
 * Uses __stack_bottom of tests/qemu/mps2_an385.ld.
 */
#ifndef BENCH_STACK_PROBE_H
#define BENCH_STACK_PROBE_H

#include <stdint.h>

/* Bytes of stack fn used, counted from the SP at the call (fn's own frame
 * and everything it calls). */
uint32_t bc_stack_probe(void (*fn)(void));

#endif /* BENCH_STACK_PROBE_H */
