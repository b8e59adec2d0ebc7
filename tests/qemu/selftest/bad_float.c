/* symcheck negative case: single-precision float. Must be rejected. */
#include <stdint.h>
int32_t st_bad_float(int32_t a, int32_t b);
int32_t st_bad_float(int32_t a, int32_t b)
{
    float x = (float)a;
    return (int32_t)(x / (float)b);
}
