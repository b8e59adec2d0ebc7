/*
 * Stack high-water mark of one call, by painting: fill the free stack below
 * the SP with a pattern, run fn, find the lowest overwritten word. Uses
 * __stack_bottom of tests/qemu/mps2_an385.ld.
 */
#ifndef BENCH_STACK_PROBE_H
#define BENCH_STACK_PROBE_H

#include <stdint.h>

/*
 * Bytes of stack used from the call that function `caller` (reached through
 * fn) makes: the SP at that call is found as the slot where the callee saved
 * its return address (the highest word in the used region that is a Thumb
 * address within BC_STACK_CALLER_SPAN bytes after `caller`; the callee's
 * prologue pushes LR first). If no such word is found, the figure counts
 * from the SP at fn's call instead (*exact = 0), which includes the frames
 * of fn and caller.
 */
#define BC_STACK_CALLER_SPAN 512u
uint32_t bc_stack_probe(void (*fn)(void), uintptr_t caller, int *exact);

#endif /* BENCH_STACK_PROBE_H */
