/* Semihosting output and command line; see report.h. */
#include "report.h"

#include "semihost.h"

#define SH_SYS_GET_CMDLINE 0x15u

void bc_puts(const char *s)
{
    it2n_sh_write0(s);
}

void bc_put_u64(uint64_t v)
{
    char buf[24];
    unsigned n = sizeof buf - 1u;
    buf[n] = '\0';
    do {
        buf[--n] = (char)('0' + (char)(v % 10u));
        v /= 10u;
    } while (v != 0u && n > 0u);
    it2n_sh_write0(&buf[n]);
}

void bc_result(const char *key1, const char *key2, uint64_t v)
{
    bc_puts("R ");
    bc_puts(key1);
    bc_puts(key2);
    bc_puts(" ");
    bc_put_u64(v);
    bc_puts("\n");
}

void bc_cmdline(char *buf, uint32_t size)
{
    uint32_t block[2];
    register uint32_t r0 __asm__("r0") = SH_SYS_GET_CMDLINE;
    register const void *r1 __asm__("r1") = block;
    block[0] = (uint32_t)(uintptr_t)buf;
    block[1] = size;
    buf[0] = '\0';
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    if (r0 != 0u) {
        buf[0] = '\0';
    }
    buf[size - 1u] = '\0';
}

int bc_has_word(const char *s, const char *word)
{
    while (*s != '\0') {
        const char *a = s, *b = word;
        while (*b != '\0' && *a == *b) {
            a++;
            b++;
        }
        if (*b == '\0' && (*a == '\0' || *a == ' ')) {
            return 1;
        }
        while (*s != '\0' && *s != ' ') {
            s++;
        }
        while (*s == ' ') {
            s++;
        }
    }
    return 0;
}
