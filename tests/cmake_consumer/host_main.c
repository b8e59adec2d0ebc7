/* Host side of the out-of-tree consumer: solve the paper model and print
 * footprint D at (u, w) in the columns of `it2n eval --decimals 9` (make test compares
 * the line with the CLI's). usage: consumer U W */
#include <stdio.h>
#include <string.h>

#include "it2n.h"
#include "it2n_proto.h"
#include "paper_model.h"

int main(int argc, char **argv)
{
    it2n_errinfo err;
    it2n_par u, w;
    it2n_val v[IT2N_CH_COUNT];
    char buf[3][32];
    int rc;
    if (argc != 3 || it2n_parse_par(argv[1], strlen(argv[1]), &u) != IT2N_OK ||
        it2n_parse_par(argv[2], strlen(argv[2]), &w) != IT2N_OK) {
        fprintf(stderr, "usage: consumer U W (each in [0, 1])\n");
        return 2;
    }
    /* the protocol library links too: CRC-32C check value */
    if (it2n_crc32c((const uint8_t *)"123456789", 9) != 0xE3069283u) {
        fprintf(stderr, "consumer: it2n_crc32c check value wrong\n");
        return 1;
    }
    rc = paper_model_solve(&err);
    if (rc == IT2N_OK) {
        rc = paper_model_eval(u, w, v, &err);
    }
    if (rc != IT2N_OK) {
        fprintf(stderr, "consumer: %s\n", it2n_strerror(rc));
        return 1;
    }
    it2n_format_par(buf[0], sizeof buf[0], u, 9);
    it2n_format_par(buf[1], sizeof buf[1], w, 9);
    printf("u,w,footprint,x,y,T,I,F\n%s,%s,D", buf[0], buf[1]);
    for (unsigned ch = 0; ch < IT2N_CH_COUNT; ch++) {
        if (ch == IT2N_CH_Z) {
            continue;
        }
        it2n_format_val(buf[2], sizeof buf[2], v[ch], 9);
        printf(",%s", buf[2]);
    }
    printf("\n");
    return 0;
}
