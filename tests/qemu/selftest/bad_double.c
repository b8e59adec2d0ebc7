/* symcheck negative case: double, through a 64-bit conversion. Must be rejected. */
#include <stdint.h>
int64_t st_bad_double(int64_t a);
int64_t st_bad_double(int64_t a)
{
    return (int64_t)((double)a * 0.5);
}
