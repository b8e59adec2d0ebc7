/*
 * Output of the benchmark images through semihosting: result lines
 * "R <key> <value> [<value> ...]" that tests/bench/mcu/results.py parses,
 * and the run mode from the semihosting command line.
 */
#ifndef BENCH_REPORT_H
#define BENCH_REPORT_H

#include <stdint.h>

void bc_puts(const char *s);
void bc_put_u64(uint64_t v);
/* "R key v\n" */
void bc_result(const char *key1, const char *key2, uint64_t v);
/* The semihosting command line (qemu -semihosting-config arg=...) into buf;
 * "" if unavailable. */
void bc_cmdline(char *buf, uint32_t size);
/* 1 if word occurs in s as a whole blank-separated word. */
int bc_has_word(const char *s, const char *word);

#endif /* BENCH_REPORT_H */
