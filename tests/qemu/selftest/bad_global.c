/* symcheck negative case: global mutable state. Must be rejected. */
#include <stdint.h>
int32_t st_bad_global(int32_t a);
int32_t st_bad_global(int32_t a)
{
    static int32_t total;
    total += a;
    return total;
}
