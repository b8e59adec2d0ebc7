/* fuzz_main.c — the plain (gcc) driver of every daemon fuzz target: runs
 * LLVMFuzzerInitialize once, then each file of a corpus directory (or the
 * single file given) plus a fixed number of seeded mutations of it (flips,
 * byte sets, truncations, duplications), so `make test` repeats the same
 * inputs on every run. Usage: fuzz_X DIR|FILE [mutations per file].
 * FUZZ_DICT=FILE: a libFuzzer dictionary ("token" lines, \xNN \\ \"
 * escapes, # comments); its tokens are also inserted by the mutations, and
 * a malformed one is an error (libFuzzer would refuse it under make fuzz). */
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

#define DICT_MAX 1024
static char *dict[DICT_MAX];
static size_t dict_len[DICT_MAX];
static unsigned ndict;

/* One "..." token of a dictionary line into dict[]; 0, or -1. */
static int dict_token(const char *l)
{
    const char *q = strchr(l, '"');
    char tok[256];
    size_t n = 0;
    if (!q || ndict == DICT_MAX)
        return -1;
    for (q++; *q && *q != '"'; q++) {
        unsigned x;
        if (n == sizeof tok)
            return -1;
        if (*q != '\\') {
            tok[n++] = *q;
        } else if (q[1] == '\\' || q[1] == '"') {
            tok[n++] = *++q;
        } else if (q[1] == 'x' && sscanf(q + 2, "%2x", &x) == 1 && strspn(q + 2, "0123456789abcdefABCDEF") >= 2) {
            tok[n++] = (char)x;
            q += 3;
        } else {
            return -1;
        }
    }
    if (*q != '"' || q[1 + strspn(q + 1, " \t\r\n")] || n == 0)
        return -1;
    dict[ndict] = malloc(n);
    if (!dict[ndict])
        return -1;
    memcpy(dict[ndict], tok, n);
    dict_len[ndict++] = n;
    return 0;
}

static void load_dict(const char *path)
{
    FILE *f = fopen(path, "r");
    char line[512];
    int no = 0;
    if (!f) {
        perror(path);
        exit(1);
    }
    while (fgets(line, sizeof line, f)) {
        const char *l = line + strspn(line, " \t");
        no++;
        if (*l == '#' || *l == '\n' || !*l)
            continue;
        if (dict_token(l)) {
            fprintf(stderr, "%s:%d: not a dictionary entry (\"token\", \\xNN \\\\ \\\" escapes)\n", path, no);
            exit(1);
        }
    }
    fclose(f);
    if (!ndict) {
        fprintf(stderr, "%s: no token\n", path);
        exit(1);
    }
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
            switch (rnd() % (ndict ? 5 : 4)) {
            case 0: mut[rnd() % m] ^= (uint8_t)(1u << (rnd() % 8)); break;
            case 1: mut[rnd() % m] = (uint8_t)rnd(); break;
            case 2: m = (size_t)(rnd() % m); break;
            case 4: { /* a dictionary token inserted anywhere */
                unsigned t = (unsigned)(rnd() % ndict);
                size_t at = (size_t)(rnd() % (m + 1));
                if (m + dict_len[t] <= sizeof mut) {
                    memmove(mut + at + dict_len[t], mut + at, m - at);
                    memcpy(mut + at, dict[t], dict_len[t]);
                    m += dict_len[t];
                }
                break;
            }
            case 3:
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

    if (getenv("FUZZ_DICT") && *getenv("FUZZ_DICT"))
        load_dict(getenv("FUZZ_DICT"));
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
    printf("%s: %u corpus file(s), %u runs%s%.0u%s, all invariants held\n", argv[0], files, runs,
           ndict ? " with " : "", ndict, ndict ? " dictionary tokens" : "");
    return files > 0 ? 0 : 1;
}
