/* symcheck negative case: heap use. Must be rejected. */
#include <stddef.h>
void *malloc(size_t n);
void *st_bad_malloc(void);
void *st_bad_malloc(void)
{
    return malloc(16);
}
