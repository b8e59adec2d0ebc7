/*
 * Freestanding start-up for the Cortex-M3 test image (qemu mps2-an385):
 * vector table, reset handler (copy .data, zero .bss, call main, report the
 * exit status) and a fault handler that fails the run instead of hanging.
 * Symbols come from mps2_an385.ld.
 */
#include <stdint.h>
#include <string.h>

#include "semihost.h"

extern uint32_t __data_load[], __data_start[], __data_end[];
extern uint32_t __bss_start[], __bss_end[];
extern uint32_t __stack_top[];

int main(void);
void it2n_reset_handler(void);
void it2n_fault_handler(void);

void it2n_reset_handler(void)
{
    size_t data_len = (size_t)((uintptr_t)__data_end - (uintptr_t)__data_start);
    size_t bss_len = (size_t)((uintptr_t)__bss_end - (uintptr_t)__bss_start);
    memcpy(__data_start, __data_load, data_len);
    memset(__bss_start, 0, bss_len);
    it2n_sh_exit(main());
}

/* Any fault (bad access, undefined instruction, stack overflow into the
 * guard) ends the run with a distinct status so `make test` fails. */
void it2n_fault_handler(void)
{
    it2n_sh_write0("FAULT: the Cortex-M3 image took a hard fault\n");
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
