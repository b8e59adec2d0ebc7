/* Instruction counter: timer 0 and the known-length loop; see counter.h. */
#include "counter.h"

#define BC_TIMER0_CTRL (*(volatile uint32_t *)0x40000000u)
#define BC_TIMER0_RELOAD (*(volatile uint32_t *)0x40000008u)

void bc_counter_start(void)
{
    BC_TIMER0_CTRL = 0u;
    BC_TIMER0_RELOAD = 0xFFFFFFFFu;
    BC_TIMER0_VALUE = 0xFFFFFFFFu;
    BC_TIMER0_CTRL = 1u; /* enable, no interrupt */
}

/* Thumb-1 (ARMv6-M) has only the flag-setting 'sub Rd, #imm' form. */
#if defined(__ARM_ARCH_6M__)
#define BC_DEC "sub %0, #1\n\t"
#else
#define BC_DEC "subs %0, %0, #1\n\t"
#endif

__attribute__((noinline)) void bc_known_loop(uint32_t iters)
{
    /* 4 instructions per iteration: sub, nop, nop, bne. */
    __asm__ volatile("1:\n\t" BC_DEC "nop\n\tnop\n\tbne 1b\n\t"
                     : "+l"(iters)
                     :
                     : "cc");
}

int bc_counter_validate(uint64_t *expected, uint64_t *measured)
{
    const uint32_t short_n = 1000u, long_n = 1001000u;
    uint32_t t0, t1, t2, t3;
    uint64_t diff, exp;
    t0 = bc_now();
    bc_known_loop(short_n);
    t1 = bc_now();
    t2 = bc_now();
    bc_known_loop(long_n);
    t3 = bc_now();
    exp = (uint64_t)BC_LOOP_BODY * (uint64_t)(long_n - short_n);
    diff = bc_instr(t2, t3) - bc_instr(t0, t1);
    *expected = exp;
    *measured = diff;
    /* |diff - exp| <= 1 % of exp */
    if ((diff > exp ? diff - exp : exp - diff) * 100u > exp) {
        return -1;
    }
    return 0;
}
