/* Stack painting; see stack_probe.h. */
#include "stack_probe.h"

extern uint32_t __stack_bottom[];

/* The pattern of tests/qemu/startup.c, so its whole-run figure stays right. */
#define BC_PAINT 0x57acc0deu

uint32_t bc_stack_probe(void (*fn)(void), uintptr_t caller, int *exact)
{
    uintptr_t sp, from, lo = caller & ~(uintptr_t)1u;
    volatile uint32_t *p;
    volatile uint32_t *end;
    volatile uint32_t *low;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    /* Everything below SP is free: no interrupts are enabled. */
    end = (volatile uint32_t *)(sp & ~(uintptr_t)3u);
    for (p = __stack_bottom; p < end; p++) {
        *p = BC_PAINT;
    }
    fn();
    for (p = __stack_bottom; p < end && *p == BC_PAINT; p++) {
    }
    low = p;
    from = sp;
    *exact = 0;
    for (p = end; p > low;) {
        uint32_t v = *--p;
        if ((v & 1u) != 0u && (v & ~1u) >= lo && (v & ~1u) < lo + BC_STACK_CALLER_SPAN) {
            from = (uintptr_t)p + 4u;
            *exact = 1;
            break;
        }
    }
    return (uint32_t)(from - (uintptr_t)low);
}
