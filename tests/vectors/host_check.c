/* Host runner for the core test vectors (the same checker as on the M3). */
#include <stdio.h>

int it2n_core_vectors_run(void (*log)(const char *));

static void host_log(const char *s)
{
    fputs(s, stdout);
}

int main(void)
{
    return it2n_core_vectors_run(host_log) == 0 ? 0 : 1;
}
