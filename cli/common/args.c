/* Command-line values shared by it2n and it2nctl: "U,W" / "X,Y" pairs,
 * "RxC" grids and footprint lists, so both tools read them alike. */
#include "cli.h"

#include <stdlib.h>
#include <string.h>

/* "A,B" -> two numbers, both parameters (Q32) or both values (Q24). */
int cli_parse_pair(const char *s, bool par, cli_at *out, const char **why)
{
    const char *comma = strchr(s, ',');
    int rc1, rc2;
    if (comma == NULL) {
        *why = "expected two numbers separated by a comma";
        return -1;
    }
    if (par) {
        rc1 = it2n_parse_par(s, (size_t)(comma - s), &out->a);
        rc2 = it2n_parse_par(comma + 1, strlen(comma + 1), &out->b);
    } else {
        rc1 = it2n_parse_val(s, (size_t)(comma - s), &out->a);
        rc2 = it2n_parse_val(comma + 1, strlen(comma + 1), &out->b);
    }
    if (rc1 == IT2N_ERR_INVAL || rc2 == IT2N_ERR_INVAL) {
        *why = "not a decimal number";
        return -1;
    }
    if (rc1 != IT2N_OK || rc2 != IT2N_OK) {
        *why = par ? "parameters must lie in [0,1]" : "coordinate beyond IT2N_COORD_LIMIT";
        return -1;
    }
    return 0;
}

/* "RxC" with R, C in 2..65535. */
bool cli_parse_grid(const char *s, unsigned *r, unsigned *c)
{
    char *end;
    unsigned long a, b;
    if (*s < '0' || *s > '9') {
        return false;
    }
    a = strtoul(s, &end, 10);
    if (*end != 'x' && *end != 'X') {
        return false;
    }
    s = end + 1;
    if (*s < '0' || *s > '9') {
        return false;
    }
    b = strtoul(s, &end, 10);
    if (*end != '\0' || a < 2 || b < 2 || a > 65535 || b > 65535) {
        return false;
    }
    *r = (unsigned)a;
    *c = (unsigned)b;
    return true;
}

/* "D", "LL,RR", ... -> bits of IT2N_FP_* (or'ed into *mask). */
bool cli_parse_fps(const char *s, unsigned *mask)
{
    for (;;) {
        size_t len = strcspn(s, ",");
        int fp = it2n_fp_from_name(s, len);
        if (len == 0u || fp < 0) {
            return false;
        }
        *mask |= 1u << (unsigned)fp;
        if (s[len] == '\0') {
            return true;
        }
        s += len + 1u;
    }
}
