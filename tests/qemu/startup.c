/*
 * Freestanding start-up for the Cortex-M test images (qemu mps2-an385/386):
 * vector table, reset handler (copy .data, zero .bss, call main, report the
 * exit status) and a fault handler that fails the run instead of hanging.
 * Symbols come from mps2_an385.ld.
 */
#include <stdint.h>
#include <string.h>

#include "semihost.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
extern uint32_t __stack_bottom[], __stack_top[];

int main(void);
void it2n_reset_handler(void);
void it2n_fault_handler(void);

#define STACK_PAINT 0x57acc0deu

/* Fill the unused stack below the current frame (less a margin) with a
 * pattern, so the high-water mark can be read back after main. */
static void paint_stack(void)
{
    volatile uint32_t here = 0;
    uint32_t *p = __stack_bottom;
    uint32_t *end = (uint32_t *)(uintptr_t)(((uintptr_t)&here - 64u) & ~(uintptr_t)3u);
    while (p < end) {
        *p++ = STACK_PAINT;
    }
    (void)here;
}

static uint32_t stack_used(void)
{
    const uint32_t *p = __stack_bottom;
    while (p < __stack_top && *p == STACK_PAINT) {
        p++;
    }
    return (uint32_t)((uintptr_t)__stack_top - (uintptr_t)p);
}

static void write_u32(const char *prefix, uint32_t v, const char *suffix)
{
    char buf[12];
    unsigned n = sizeof buf - 1u;
    buf[n] = '\0';
    do {
        buf[--n] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && n > 0u);
    it2n_sh_write0(prefix);
    it2n_sh_write0(&buf[n]);
    it2n_sh_write0(suffix);
}

void it2n_reset_handler(void)
{
    size_t data_len = (size_t)((uintptr_t)__data_end - (uintptr_t)__data_start);
    size_t bss_len = (size_t)((uintptr_t)__bss_end - (uintptr_t)__bss_start);
    int rc;
    memcpy(__data_start, __data_load, data_len);
    memset(__bss_start, 0, bss_len);
    paint_stack();
    rc = main();
    write_u32("stack high-water mark: ", stack_used(), " bytes of ");
    write_u32("", (uint32_t)((uintptr_t)__stack_top - (uintptr_t)__stack_bottom), "\n");
    it2n_sh_exit(rc);
}

/* Any fault (bad access, undefined instruction, stack overflow into the
 * guard) ends the run with a distinct status so `make test` fails. */
void it2n_fault_handler(void)
{
    it2n_sh_write0("FAULT: the test image took a hard fault\n");
    it2n_sh_exit(3);
}

typedef void (*it2n_vector)(void);

/* Initial SP, reset, then NMI .. SysTick (exceptions 2..15). */
__attribute__((section(".vectors"), used))
const it2n_vector it2n_vector_table[16] = {
    (it2n_vector)(uintptr_t)__stack_top,
    it2n_reset_handler,
    it2n_fault_handler, /* NMI        */
    it2n_fault_handler, /* HardFault  */
    it2n_fault_handler, /* MemManage  */
    it2n_fault_handler, /* BusFault   */
    it2n_fault_handler, /* UsageFault */
    0, 0, 0, 0,
    it2n_fault_handler, /* SVCall     */
    it2n_fault_handler, /* DebugMon   */
    0,
    it2n_fault_handler, /* PendSV     */
    it2n_fault_handler, /* SysTick    */
};
