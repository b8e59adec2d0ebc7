/* ARM semihosting calls used by the Cortex-M test images. */
#include "semihost.h"

#include <stdint.h>

#define SH_SYS_OPEN 0x01u
#define SH_SYS_CLOSE 0x02u
#define SH_SYS_READ 0x06u
#define SH_SYS_WRITE0 0x04u
#define SH_SYS_EXIT 0x18u
#define SH_SYS_EXIT_EXTENDED 0x20u
#define SH_ADP_APPLICATION_EXIT 0x20026u

/* r0 = operation, r1 = argument; the debugger (qemu) answers in r0. */
static uint32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void it2n_sh_write0(const char *s)
{
    (void)sh_call(SH_SYS_WRITE0, s);
}

void it2n_sh_exit(int code)
{
    /* The parameter block must stay valid during the call: it does, the
     * call never returns. */
    uint32_t block[2];
    block[0] = SH_ADP_APPLICATION_EXIT;
    block[1] = (uint32_t)code;
    (void)sh_call(SH_SYS_EXIT_EXTENDED, block);
    /* Older hosts without the extension: plain SYS_EXIT maps "application
     * exit" to status 0 and anything else to 1, which keeps pass/fail. */
    (void)sh_call(SH_SYS_EXIT, (const void *)(uintptr_t)(code == 0 ? SH_ADP_APPLICATION_EXIT : 0x20023u));
    for (;;) {
    }
}

int it2n_sh_read_file(const char *path, char *buf, unsigned len)
{
    uint32_t block[3];
    uint32_t n = 0, h, left;
    if (len == 0u)
        return -1;
    while (path[n] != '\0')
        n++;
    block[0] = (uint32_t)(uintptr_t)path;
    block[1] = 0u; /* "r" */
    block[2] = n;
    h = sh_call(SH_SYS_OPEN, block);
    if (h == 0xFFFFFFFFu)
        return -1;
    block[0] = h;
    block[1] = (uint32_t)(uintptr_t)buf;
    block[2] = len - 1u;
    left = sh_call(SH_SYS_READ, block); /* bytes NOT read */
    n = left <= len - 1u ? len - 1u - left : 0u;
    buf[n] = '\0';
    block[0] = h;
    (void)sh_call(SH_SYS_CLOSE, block);
    return (int)n;
}
