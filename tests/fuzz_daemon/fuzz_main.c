/* fuzz_main.c — the plain (gcc) driver of every daemon fuzz target: runs
 * LLVMFuzzerInitialize once, then each file of a corpus directory (or the
 * single file given) plus a fixed number of seeded mutations of it (flips,
 * byte sets, truncations, duplications), so `make test` repeats the same
 * inputs on every run. Usage: fuzz_X DIR|FILE [mutations per file]. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FUZZ_MAX_INPUT (1u << 17)

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static uint64_t rnd(void)
{
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return rng_state * 0x2545F4914F6CDD1Dull;
}

static unsigned run_file(const char *path, unsigned mutations)
{
    static uint8_t buf[FUZZ_MAX_INPUT], mut[FUZZ_MAX_INPUT];
    FILE *f = fopen(path, "rb");
    unsigned runs = 0;
    if (f == NULL) {
        perror(path);
        exit(1);
    }
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    LLVMFuzzerTestOneInput(buf, n);
    runs++;
    for (unsigned k = 0; k < mutations; k++) {
        size_t m = n;
        memcpy(mut, buf, n);
        unsigned ops = 1 + (unsigned)(rnd() % 4);
        for (unsigned o = 0; o < ops && m > 0; o++) {
            switch (rnd() % 4) {
            case 0: mut[rnd() % m] ^= (uint8_t)(1u << (rnd() % 8)); break;
            case 1: mut[rnd() % m] = (uint8_t)rnd(); break;
            case 2: m = (size_t)(rnd() % m); break;
            default:
                if (m < sizeof mut / 2) {
                    memcpy(mut + m, mut, m);
                    m *= 2;
                }
                break;
            }
        }
        LLVMFuzzerTestOneInput(mut, m);
        runs++;
    }
    return runs;
}

int main(int argc, char **argv)
{
    const char *arg = argc > 1 ? argv[1] : ".";
    unsigned mutations = argc > 2 ? (unsigned)strtoul(argv[2], NULL, 10) : 100;
    unsigned files = 0, runs = 0;
    struct stat st;
    char path[4096];

    LLVMFuzzerInitialize(&argc, &argv);
    if (stat(arg, &st) == 0 && S_ISREG(st.st_mode)) {
        runs = run_file(arg, mutations);
        files = 1;
    } else {
        struct dirent **names;
        int n = scandir(arg, &names, NULL, alphasort); /* fixed order */
        if (n < 0) {
            perror(arg);
            return 1;
        }
        for (int k = 0; k < n; k++) {
            if (names[k]->d_name[0] != '.') {
                snprintf(path, sizeof path, "%s/%s", arg, names[k]->d_name);
                runs += run_file(path, mutations);
                files++;
            }
            free(names[k]);
        }
        free(names);
    }
    printf("%s: %u corpus file(s), %u runs, all invariants held\n", argv[0], files, runs);
    return files > 0 ? 0 : 1;
}
