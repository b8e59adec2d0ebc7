/* symcheck positive control: integer maths, libgcc helpers, memcpy. Must pass. */
#include <stdint.h>
#include <string.h>
int64_t st_good(int64_t a, int64_t b, const int64_t *src, int64_t *dst);
int64_t st_good(int64_t a, int64_t b, const int64_t *src, int64_t *dst)
{
    memcpy(dst, src, 8u * sizeof *dst); /* large enough to stay a call */
    return (a * b) / (b | 1) + (int64_t)((uint64_t)a % 7u);
}
