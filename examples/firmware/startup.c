/*
 * Start-up of the emulated instrument firmware (qemu mps2-an385): vector
 * table with SysTick and the UART0 receive interrupt, reset handler (copy
 * .data, zero .bss, run main, exit through semihosting with its status).
 * Memory layout: tests/qemu/mps2_an385.ld.
 */
#include <stdint.h>
#include <string.h>

#include "semihost.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
extern uint32_t __stack_bottom[], __stack_top[];

int main(void);
void fw_reset_handler(void);
void fw_fault_handler(void);
void fw_uart0_rx_isr(void);
void fw_systick_isr(void);

#define STACK_PAINT 0x57acc0deu

/* Paint the stack below the current frame, read the high-water mark back
 * after main (worst case of this run, interrupts included). */
static void paint_stack(void)
{
    volatile uint32_t here = 0;
    uintptr_t lo = (uintptr_t)__stack_bottom;
    uintptr_t hi = ((uintptr_t)&here - 64u) & ~(uintptr_t)3u;
    size_t k, words = hi > lo ? (size_t)((hi - lo) / 4u) : 0u;
    for (k = 0; k < words; k++)
        __stack_bottom[k] = STACK_PAINT;
    (void)here;
}

static void print_stack_used(void)
{
    size_t size = (size_t)((uintptr_t)__stack_top - (uintptr_t)__stack_bottom);
    size_t k = 0, words = size / 4u;
    char buf[12];
    unsigned n = sizeof buf - 1u;
    uint32_t v;
    while (k < words && __stack_bottom[k] == STACK_PAINT)
        k++;
    v = (uint32_t)(size - k * 4u);
    buf[n] = '\0';
    do {
        buf[--n] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && n > 0u);
    it2n_sh_write0("STACK high-water bytes ");
    it2n_sh_write0(&buf[n]);
    it2n_sh_write0("\n");
}

void fw_reset_handler(void)
{
    int rc;
    size_t data_len = (size_t)((uintptr_t)__data_end - (uintptr_t)__data_start);
    size_t bss_len = (size_t)((uintptr_t)__bss_end - (uintptr_t)__bss_start);
    memcpy(__data_start, __data_load, data_len);
    memset(__bss_start, 0, bss_len);
    paint_stack();
    rc = main();
    print_stack_used();
    it2n_sh_exit(rc);
}

void fw_fault_handler(void)
{
    it2n_sh_write0("FAIL: firmware fault or unexpected exception\n");
    it2n_sh_exit(3);
}

typedef void (*fw_vector)(void);

/* Exceptions 0..15, then external IRQ 0 (UART0 RX) .. 15. */
/* clang-format off */
__attribute__((section(".vectors"), used))
const fw_vector fw_vector_table[32] = {
    (fw_vector)(uintptr_t)__stack_top,
    fw_reset_handler,
    fw_fault_handler, /* NMI        */
    fw_fault_handler, /* HardFault  */
    fw_fault_handler, /* MemManage  */
    fw_fault_handler, /* BusFault   */
    fw_fault_handler, /* UsageFault */
    0, 0, 0, 0,
    fw_fault_handler, /* SVCall     */
    fw_fault_handler, /* DebugMon   */
    0,
    fw_fault_handler, /* PendSV     */
    fw_systick_isr,   /* SysTick    */
    fw_uart0_rx_isr,  /* IRQ 0: UART0 receive */
    fw_fault_handler, fw_fault_handler, fw_fault_handler, fw_fault_handler,
    fw_fault_handler, fw_fault_handler, fw_fault_handler, fw_fault_handler,
    fw_fault_handler, fw_fault_handler, fw_fault_handler, fw_fault_handler,
    fw_fault_handler, fw_fault_handler, fw_fault_handler,
};
/* clang-format on */
