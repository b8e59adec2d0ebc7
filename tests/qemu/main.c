/*
 * Cortex-M test image: runs the core test vectors (tests/vectors/) and, when
 * the protocol self-test is built in, it2n_proto_selftest(). Prints PASS or
 * FAIL lines through semihosting; the exit status is what `make test` checks.
 */
#include "semihost.h"

int it2n_core_vectors_run(void (*log)(const char *));
#ifdef IT2N_HAVE_PROTO_SELFTEST
int it2n_proto_selftest(void);
#endif
int main(void);

static void qemu_log(const char *s)
{
    it2n_sh_write0(s);
}

int main(void)
{
    int failed = 0;

#if defined(__ARM_ARCH_6M__)
    it2n_sh_write0("it2n test image, ARMv6-M code (Cortex-M0+)\n");
#elif defined(__ARM_ARCH_7EM__)
    it2n_sh_write0("it2n test image, ARMv7E-M code (Cortex-M4)\n");
#else
    it2n_sh_write0("it2n test image, ARMv7-M code (Cortex-M3)\n");
#endif
    if (it2n_core_vectors_run(qemu_log) != 0) {
        it2n_sh_write0("FAIL: core vectors\n");
        failed = 1;
    } else {
        it2n_sh_write0("PASS: core vectors\n");
    }
#ifdef IT2N_HAVE_PROTO_SELFTEST
    if (it2n_proto_selftest() != 0) {
        it2n_sh_write0("FAIL: protocol self-test\n");
        failed = 1;
    } else {
        it2n_sh_write0("PASS: protocol self-test\n");
    }
#endif
    return failed;
}
