/*
 * main of the benchmark images: on a part with an FPU, enable it (CPACR
 * CP10/CP11 full access) before any floating-point instruction runs, then
 * hand over to bench_main (another translation unit, so none of its FPU code
 * can be scheduled before the enable).
 */
#include <stdint.h>

int main(void);
int bench_main(void);

int main(void)
{
#if defined(__ARM_FP)
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
#endif
    return bench_main();
}
