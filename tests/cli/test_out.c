/*
 * cmocka tests of the front ends' output layer (cli/common/out.c): the CSV
 * rows it2n and it2nctl print, byte for byte (z column or not, type-1,
 * --footprint, --decimals, parameters' minimum digits, out_of_range names,
 * the summary rows, locate rows with and without (u, w)).
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "cli.h"
#include "out.h"

static char *g_buf;
static size_t g_len;
static FILE *g_saved;

static void capture(void)
{
    g_saved = stdout;
    stdout = open_memstream(&g_buf, &g_len);
    assert_non_null(stdout);
}

/* What was printed, checked against want. */
static void expect(const char *want)
{
    fclose(stdout);
    stdout = g_saved;
    assert_string_equal(g_buf, want);
    free(g_buf);
}

#define V(x) ((it2n_val)((x) * (double)IT2N_VAL_ONE))
#define HALF ((it2n_par)1 << 31)

static void test_values_and_parameters(void **state)
{
    (void)state;
    capture();
    cli_put_val(V(0.5), 3);
    putchar(' ');
    cli_put_val(V(-1.25), 0); /* ties away from zero */
    putchar(' ');
    cli_put_par(HALF, 2);     /* parameters keep 6 digits */
    putchar(' ');
    cli_put_par(HALF, 9);
    expect("0.500 -1 0.500000 0.500000000");
}

static void test_header_and_net_rows(void **state)
{
    const it2n_val v[IT2N_CH_COUNT] = {V(1), V(2), V(3), V(0.25), V(0.5), V(0.75)};
    cli_out w;
    (void)state;
    cli_out_init(&w, 0u, 2, 0u, false);
    capture();
    cli_put_header(&w, "i,j,footprint", "");
    cli_put_net_row(&w, -1, 3, IT2N_FP_RL, v);
    expect("i,j,footprint,x,y,T,I,F\n-1,3,RL,1.00,2.00,0.25,0.50,0.75\n");
    cli_out_init(&w, IT2N_F_Z, 1, 0u, false);
    capture();
    cli_put_header(&w, "u,w,footprint", ",out_of_range");
    cli_put_net_row(&w, 0, 0, IT2N_FP_D, v);
    expect("u,w,footprint,x,y,z,T,I,F,out_of_range\n0,0,D,1.0,2.0,3.0,0.3,0.5,0.8\n");
}

static void test_point_rows(void **state)
{
    it2n_point pt;
    unsigned fp;
    cli_out w;
    (void)state;
    memset(&pt, 0, sizeof(pt));
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        pt.v[fp][IT2N_CH_X] = V(fp);
        pt.v[fp][IT2N_CH_T] = V(0.5);
    }
    pt.v[IT2N_FP_LL][IT2N_CH_T] = V(1.5);
    pt.v[IT2N_FP_LL][IT2N_CH_F] = V(-0.25);
    pt.out_of_range = (1u << (IT2N_FP_LL * 3u)) | (4u << (IT2N_FP_LL * 3u));
    pt.sum.upper_min[0] = V(0.5);
    pt.sum.upper_max[0] = V(1.5);
    pt.sum.lower_min[2] = V(-0.25);
    /* --footprint LL,D; --summary; 1 decimal */
    cli_out_init(&w, 0u, 1, (1u << IT2N_FP_LL) | (1u << IT2N_FP_D), true);
    capture();
    cli_put_point(&w, HALF, 0, &pt);
    expect("0.500000,0.000000,LL,0.0,0.0,1.5,0.0,-0.3,T|F\n"
           "0.500000,0.000000,D,3.0,0.0,0.5,0.0,0.0,-\n"
           "0.500000,0.000000,upper_min,,,0.5,0.0,0.0,-\n"
           "0.500000,0.000000,upper_max,,,1.5,0.0,0.0,T\n"
           "0.500000,0.000000,lower_min,,,0.0,0.0,-0.3,F\n"
           "0.500000,0.000000,lower_max,,,0.0,0.0,0.0,-\n");
    /* a type-1 model prints D only, whatever the mask */
    cli_out_init(&w, IT2N_F_TYPE1 | IT2N_F_Z, 0, 0u, false);
    capture();
    cli_put_point(&w, 0, HALF, &pt);
    expect("0.000000,0.500000,D,3,0,0,1,0,0,-\n");
    assert_false(cli_out_has_fp(&w, IT2N_FP_LL));
    assert_true(cli_out_has_fp(&w, IT2N_FP_D));
}

static void test_locate_rows(void **state)
{
    const it2n_val v[IT2N_CH_COUNT] = {0, 0, V(7), V(0.125), V(1), 0};
    const it2n_par uw[2] = {HALF, (it2n_par)1 << 32};
    cli_out w;
    (void)state;
    cli_out_init(&w, IT2N_F_Z, 3, 0u, false);
    capture();
    cli_put_locate_row(&w, V(1), V(-2), IT2N_FP_R, uw, v, "inside");
    cli_put_locate_row(&w, V(1), V(-2), IT2N_FP_R, NULL, v, "outside|noconv");
    expect("1.000,-2.000,R,0.500000,1.000000,7.000,0.125,1.000,0.000,inside\n"
           "1.000,-2.000,R,,,7.000,0.125,1.000,0.000,outside|noconv\n");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_values_and_parameters),
        cmocka_unit_test(test_header_and_net_rows),
        cmocka_unit_test(test_point_rows),
        cmocka_unit_test(test_locate_rows),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
