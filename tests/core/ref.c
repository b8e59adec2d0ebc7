/* Long-double reference solver; see ref.h. */
#include "ref.h"

#include <math.h>
#include <string.h>

void ref_bernstein(unsigned n, long double t, long double b[REF_D])
{
    /* de Casteljau-style build-up: stable and exact at t = 0 and t = 1. */
    long double s = 1.0L - t;
    b[0] = 1.0L;
    for (unsigned k = 1; k <= n; k++) {
        long double saved = 0.0L;
        for (unsigned i = 0; i < k; i++) {
            long double tmp = b[i];
            b[i] = saved + s * tmp;
            saved = t * tmp;
        }
        b[k] = saved;
    }
}

/* Invert the (k x k) matrix a into inv by Gauss-Jordan with partial
 * pivoting. Returns -1 if singular. */
static int ref_invert(unsigned k, long double a[REF_D][REF_D],
                      long double inv[REF_D][REF_D])
{
    long double w[REF_D][2 * REF_D];
    for (unsigned r = 0; r < k; r++)
        for (unsigned c = 0; c < 2 * k; c++)
            w[r][c] = c < k ? a[r][c] : (c - k == r ? 1.0L : 0.0L);
    for (unsigned c = 0; c < k; c++) {
        unsigned p = c;
        for (unsigned r = c + 1; r < k; r++)
            if (fabsl(w[r][c]) > fabsl(w[p][c]))
                p = r;
        if (fabsl(w[p][c]) < 1e-30L)
            return -1;
        if (p != c)
            for (unsigned x = 0; x < 2 * k; x++) {
                long double t = w[p][x];
                w[p][x] = w[c][x];
                w[c][x] = t;
            }
        for (unsigned r = 0; r < k; r++) {
            if (r == c)
                continue;
            long double f = w[r][c] / w[c][c];
            for (unsigned x = c; x < 2 * k; x++)
                w[r][x] -= f * w[c][x];
        }
    }
    for (unsigned r = 0; r < k; r++)
        for (unsigned c = 0; c < k; c++)
            inv[r][c] = w[r][k + c] / w[r][r];
    return 0;
}

static long double ref_dist(const ref_model *r, unsigned fp, unsigned i0,
                            unsigned j0, unsigned i1, unsigned j1)
{
    long double dx = r->data[i1][j1][fp][IT2N_CH_X] - r->data[i0][j0][fp][IT2N_CH_X];
    long double dy = r->data[i1][j1][fp][IT2N_CH_Y] - r->data[i0][j0][fp][IT2N_CH_Y];
    long double dz = (r->flags & IT2N_F_Z)
        ? r->data[i1][j1][fp][IT2N_CH_Z] - r->data[i0][j0][fp][IT2N_CH_Z] : 0.0L;
    return sqrtl(dx * dx + dy * dy + dz * dz);
}

/* One direction of A9.3: average over the lines of the normalised
 * cumulative chord lengths; lines of zero length are skipped. */
static int ref_chord_dir(const ref_model *r, unsigned fp, bool along_u,
                         long double out[REF_D])
{
    unsigned deg = along_u ? r->n : r->m, lines = along_u ? r->m : r->n;
    unsigned num = lines + 1;
    long double acc[REF_D] = {0};
    for (unsigned l = 0; l <= lines; l++) {
        long double cd[REF_D], total = 0.0L;
        for (unsigned k = 1; k <= deg; k++) {
            cd[k] = along_u ? ref_dist(r, fp, k - 1, l, k, l)
                            : ref_dist(r, fp, l, k - 1, l, k);
            total += cd[k];
        }
        if (total == 0.0L) {
            num--;
            continue;
        }
        long double d = 0.0L;
        for (unsigned k = 1; k < deg; k++) {
            d += cd[k];
            acc[k] += d / total;
        }
    }
    if (num == 0)
        return -1;
    out[0] = 0.0L;
    for (unsigned k = 1; k < deg; k++)
        out[k] = acc[k] / (long double)num;
    out[deg] = 1.0L;
    return 0;
}

int ref_chord_params(const ref_model *r, unsigned fp, long double u[REF_D],
                     long double w[REF_D])
{
    if (ref_chord_dir(r, fp, true, u) != 0 || ref_chord_dir(r, fp, false, w) != 0)
        return -1;
    return 0;
}

int ref_solve(ref_model *r, unsigned chord_fp)
{
    if (r->flags & IT2N_F_CHORD) {
        if (ref_chord_params(r, chord_fp, r->u, r->w) != 0)
            return -1;
    } else {
        for (unsigned k = 0; k <= r->n; k++)
            r->u[k] = (long double)k / (long double)r->n;
        for (unsigned k = 0; k <= r->m; k++)
            r->w[k] = (long double)k / (long double)r->m;
    }
    return ref_solve_params(r);
}

int ref_solve_params(ref_model *r)
{
    long double mm[REF_D][REF_D], nn[REF_D][REF_D];
    long double mi[REF_D][REF_D], ni[REF_D][REF_D];
    for (unsigned k = 0; k <= r->n; k++)
        ref_bernstein(r->n, r->u[k], mm[k]); /* mm[k][i] = B_i(u_k) */
    for (unsigned k = 0; k <= r->m; k++)
        ref_bernstein(r->m, r->w[k], nn[k]);
    if (ref_invert(r->n + 1, mm, mi) != 0 || ref_invert(r->m + 1, nn, ni) != 0)
        return -1;
    /* data = mm * P * nn^T  =>  P = mi * data * ni^T */
    memset(r->ctrl, 0, sizeof r->ctrl);
    for (unsigned fp = 0; fp < REF_FP; fp++)
        for (unsigned ch = 0; ch < REF_CH; ch++)
            for (unsigned i = 0; i <= r->n; i++)
                for (unsigned j = 0; j <= r->m; j++) {
                    long double s = 0.0L;
                    for (unsigned k = 0; k <= r->n; k++)
                        for (unsigned l = 0; l <= r->m; l++)
                            s += mi[i][k] * r->data[k][l][fp][ch] * ni[j][l];
                    r->ctrl[i][j][fp][ch] = s;
                }
    return 0;
}

void ref_eval(const ref_model *r, long double u, long double w,
              long double out[REF_FP][REF_CH])
{
    long double bu[REF_D], bw[REF_D];
    ref_bernstein(r->n, u, bu);
    ref_bernstein(r->m, w, bw);
    for (unsigned fp = 0; fp < REF_FP; fp++)
        for (unsigned ch = 0; ch < REF_CH; ch++) {
            long double s = 0.0L;
            for (unsigned i = 0; i <= r->n; i++)
                for (unsigned j = 0; j <= r->m; j++)
                    s += bu[i] * bw[j] * r->ctrl[i][j][fp][ch];
            out[fp][ch] = s;
        }
}

void ref_deriv_fd(const ref_model *r, long double u, long double w,
                  long double h, long double du[REF_FP][REF_CH],
                  long double dw[REF_FP][REF_CH])
{
    /* Bernstein polynomials extend beyond [0,1], so the centred stencil is
     * valid at the borders too. */
    long double a[REF_FP][REF_CH], b[REF_FP][REF_CH];
    ref_eval(r, u + h, w, a);
    ref_eval(r, u - h, w, b);
    for (unsigned fp = 0; fp < REF_FP; fp++)
        for (unsigned ch = 0; ch < REF_CH; ch++)
            du[fp][ch] = (a[fp][ch] - b[fp][ch]) / (2.0L * h);
    ref_eval(r, u, w + h, a);
    ref_eval(r, u, w - h, b);
    for (unsigned fp = 0; fp < REF_FP; fp++)
        for (unsigned ch = 0; ch < REF_CH; ch++)
            dw[fp][ch] = (a[fp][ch] - b[fp][ch]) / (2.0L * h);
}
