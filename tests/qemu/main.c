/*
 * Cortex-M3 test image: runs the core test vectors (tests/vectors/) and, when
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

    it2n_sh_write0("it2n Cortex-M3 image (qemu mps2-an385)\n");
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
