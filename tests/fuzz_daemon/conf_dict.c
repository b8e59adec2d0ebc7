/* conf_dict — prints the config fuzzer's dictionary (section headers,
 * "key = " of every key, enum words and range ends) from the schema
 * (daemon/conf_schema.c), so the dictionary cannot miss a key the parser
 * takes. Used by fuzzd-corpus (the plain driver's token mutations) and
 * fuzzd-fuzz-conf (libFuzzer -dict=). */
#include <stdio.h>

#include "conf_schema.h"

int main(void)
{
    if (conf_schema_print(stdout, "dict"))
        return 1;
    return fflush(stdout) ? 1 : 0;
}
