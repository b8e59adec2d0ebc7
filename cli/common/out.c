/* The CSV rows of it2n and it2nctl (out.h). */
#include "out.h"
#include "cli.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

void cli_out_init(cli_out *w, unsigned flags, unsigned decimals, unsigned fpmask, bool summary)
{
    w->z = (flags & IT2N_F_Z) != 0u;
    w->type1 = (flags & IT2N_F_TYPE1) != 0u;
    w->decimals = decimals;
    w->fpmask = fpmask;
    w->summary = summary;
}

bool cli_out_has_fp(const cli_out *w, unsigned fp)
{
    return w->type1 ? fp == IT2N_FP_D : fp < IT2N_FP_COUNT;
}

bool cli_out_selected(const cli_out *w, unsigned fp)
{
    return cli_out_has_fp(w, fp) && (w->fpmask == 0u || (w->fpmask & (1u << fp)) != 0u);
}

void cli_put_val(it2n_val v, unsigned decimals)
{
    char buf[48];
    cli_fmt_val(buf, sizeof(buf), v, decimals);
    fputs(buf, stdout);
}

/* Parameters keep at least CLI_PAR_DECIMALS digits: --decimals below that
 * shortens values, never the (u, w) a row is about. */
void cli_put_par(it2n_par p, unsigned decimals)
{
    char buf[48];
    if (decimals < CLI_PAR_DECIMALS) {
        decimals = CLI_PAR_DECIMALS;
    }
    if (it2n_format_par(buf, sizeof(buf), p, decimals) < 0) {
        fputs("?", stdout); /* cannot happen: buf fits any int64 */
        return;
    }
    fputs(buf, stdout);
}

void cli_put_header(const cli_out *w, const char *lead, const char *tail)
{
    printf("%s,x,y%s,T,I,F%s\n", lead, w->z ? ",z" : "", tail);
}

void cli_put_channels(const cli_out *w, const it2n_val *v)
{
    unsigned ch;
    for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
        if (ch == IT2N_CH_Z && !w->z) {
            continue;
        }
        putchar(',');
        cli_put_val(v[ch], w->decimals);
    }
}

void cli_put_net_row(const cli_out *w, int i, int j, unsigned fp, const it2n_val *v)
{
    printf("%d,%d,%s", i, j, it2n_fp_name(fp));
    cli_put_channels(w, v);
    putchar('\n');
}

/* ",T|I|F" of the memberships flagged (bits 0..2 of bits), or ",-". */
static void put_flags(unsigned bits)
{
    static const char *const tif[3] = {"T", "I", "F"};
    bool any = false;
    unsigned k;
    putchar(',');
    for (k = 0; k < 3u; k++) {
        if (bits & (1u << k)) {
            printf("%s%s", any ? "|" : "", tif[k]);
            any = true;
        }
    }
    if (!any) {
        putchar('-');
    }
}

/* A summary row: coordinates empty, T,I,F filled, flags from the values. */
static void put_summary_row(const cli_out *w, it2n_par u, it2n_par wp, const char *what, const it2n_val tif[3])
{
    unsigned k, bits = 0;
    cli_put_par(u, w->decimals);
    putchar(',');
    cli_put_par(wp, w->decimals);
    printf(",%s,,%s", what, w->z ? "," : ""); /* x, y (, z) empty */
    for (k = 0; k < 3u; k++) {
        putchar(',');
        cli_put_val(tif[k], w->decimals);
        if (tif[k] < 0 || tif[k] > IT2N_VAL_ONE) {
            bits |= 1u << k;
        }
    }
    put_flags(bits);
    putchar('\n');
}

void cli_put_point(const cli_out *w, it2n_par u, it2n_par wp, const it2n_point *pt)
{
    unsigned fp;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        if (!cli_out_selected(w, fp)) {
            continue;
        }
        cli_put_par(u, w->decimals);
        putchar(',');
        cli_put_par(wp, w->decimals);
        printf(",%s", it2n_fp_name(fp));
        cli_put_channels(w, pt->v[fp]);
        put_flags((unsigned)(pt->out_of_range >> (fp * 3u)) & 7u);
        putchar('\n');
    }
    if (w->summary) {
        put_summary_row(w, u, wp, "upper_min", pt->sum.upper_min);
        put_summary_row(w, u, wp, "upper_max", pt->sum.upper_max);
        put_summary_row(w, u, wp, "lower_min", pt->sum.lower_min);
        put_summary_row(w, u, wp, "lower_max", pt->sum.lower_max);
    }
}

void cli_put_locate_row(const cli_out *w, it2n_val x, it2n_val y, unsigned fp, const it2n_par *uw, const it2n_val *v,
                        const char *status)
{
    unsigned ch;
    cli_put_val(x, w->decimals);
    putchar(',');
    cli_put_val(y, w->decimals);
    printf(",%s,", it2n_fp_name(fp));
    if (uw != NULL) {
        cli_put_par(uw[0], w->decimals);
        putchar(',');
        cli_put_par(uw[1], w->decimals);
    } else {
        putchar(',');
    }
    for (ch = w->z ? IT2N_CH_Z : IT2N_CH_T; ch < IT2N_CH_COUNT; ch++) {
        putchar(',');
        cli_put_val(v[ch], w->decimals);
    }
    printf(",%s\n", status);
}

int cli_put_sample_row(void *ctx, unsigned r, unsigned c, it2n_par u, it2n_par wp, const it2n_point *pt)
{
    (void)r;
    (void)c;
    cli_put_point(ctx, u, wp, pt);
    return ferror(stdout) ? CLI_EXIT_DATA : CLI_EXIT_OK;
}

int cli_finish_output(const char *prog)
{
    if (fflush(stdout) != 0 || ferror(stdout)) {
        fprintf(stderr, "%s: write error: %s\n", prog, strerror(errno));
        return 2;
    }
    return 0;
}
