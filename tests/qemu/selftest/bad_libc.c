/* symcheck negative case: a libc function beyond memcpy/memset/memmove. */
#include <stddef.h>
size_t strlen(const char *s);
size_t st_bad_libc(const char *s);
size_t st_bad_libc(const char *s)
{
    return strlen(s);
}
