/*
 * The baseline code, written once for a type: include with BL_T (float or
 * double) and BL_P (the name prefix) defined. See baseline.h.
 */
#define BL_CAT2(a, b) a##_##b
#define BL_CAT(a, b) BL_CAT2(a, b)
#define BL_FN(name) BL_CAT(BL_P, name)
#define BL_MODEL BL_CAT(BL_P, model)
#define BL_POINT BL_CAT(BL_P, point)
#define BL_DATA BL_CAT(BL_P, data)

void BL_FN(bernstein)(unsigned n, BL_T t, BL_T b[BL_DIM])
{
    BL_T s = (BL_T)1 - t;
    unsigned k, i;
    b[0] = (BL_T)1;
    for (k = 1; k <= n; k++) {
        BL_T saved = (BL_T)0;
        for (i = 0; i < k; i++) {
            BL_T tmp = b[i];
            b[i] = saved + s * tmp;
            saved = t * tmp;
        }
        b[k] = saved;
    }
}

static BL_T BL_FN(abs)(BL_T x)
{
    return x < (BL_T)0 ? -x : x;
}

/* inv = a^-1 for the k x k matrix a (destroyed): Gauss-Jordan with partial
 * pivoting. 0, or -1 if singular. */
static int BL_FN(invert)(unsigned k, BL_T a[BL_DIM][BL_DIM], BL_T inv[BL_DIM][BL_DIM])
{
    unsigned r, c, x, p;
    for (r = 0; r < k; r++) {
        for (c = 0; c < k; c++) {
            inv[r][c] = r == c ? (BL_T)1 : (BL_T)0;
        }
    }
    for (c = 0; c < k; c++) {
        BL_T piv;
        p = c;
        for (r = c + 1; r < k; r++) {
            if (BL_FN(abs)(a[r][c]) > BL_FN(abs)(a[p][c])) {
                p = r;
            }
        }
        if (a[p][c] == (BL_T)0) {
            return -1;
        }
        if (p != c) {
            for (x = 0; x < k; x++) {
                BL_T t = a[p][x];
                a[p][x] = a[c][x];
                a[c][x] = t;
                t = inv[p][x];
                inv[p][x] = inv[c][x];
                inv[c][x] = t;
            }
        }
        piv = (BL_T)1 / a[c][c];
        for (x = 0; x < k; x++) {
            a[c][x] *= piv;
            inv[c][x] *= piv;
        }
        for (r = 0; r < k; r++) {
            BL_T f = a[r][c];
            if (r == c || f == (BL_T)0) {
                continue;
            }
            for (x = 0; x < k; x++) {
                a[r][x] -= f * a[c][x];
                inv[r][x] -= f * inv[c][x];
            }
        }
    }
    return 0;
}

/* Rows k: basis of degree n at t_k = k/n. */
static void BL_FN(collocation)(unsigned n, BL_T a[BL_DIM][BL_DIM])
{
    unsigned k;
    for (k = 0; k <= n; k++) {
        BL_FN(bernstein)(n, (BL_T)k / (BL_T)n, a[k]);
    }
}

int BL_FN(solve)(BL_MODEL *mdl, unsigned n, unsigned m, const BL_DATA *f)
{
    BL_T a[BL_DIM][BL_DIM], ai[BL_DIM][BL_DIM];
    BL_T b[BL_DIM][BL_DIM], bi[BL_DIM][BL_DIM];
    BL_T tmp[BL_DIM][BL_DIM];
    unsigned fp, ch, i, j, k;
    BL_FN(collocation)(n, a);
    BL_FN(collocation)(m, b);
    if (BL_FN(invert)(n + 1, a, ai) != 0 || BL_FN(invert)(m + 1, b, bi) != 0) {
        return -1;
    }
    mdl->n = n;
    mdl->m = m;
    for (fp = 0; fp < BL_FP; fp++) {
        for (ch = 0; ch < BL_CH; ch++) {
            const BL_T(*d)[BL_DIM] = (*f)[fp][ch];
            BL_T(*p)[BL_DIM] = mdl->p[fp][ch];
            /* tmp = M^-1 F */
            for (i = 0; i <= n; i++) {
                for (j = 0; j <= m; j++) {
                    BL_T s = (BL_T)0;
                    for (k = 0; k <= n; k++) {
                        s += ai[i][k] * d[k][j];
                    }
                    tmp[i][j] = s;
                }
            }
            /* P = tmp N^-T */
            for (i = 0; i <= n; i++) {
                for (j = 0; j <= m; j++) {
                    BL_T s = (BL_T)0;
                    for (k = 0; k <= m; k++) {
                        s += tmp[i][k] * bi[j][k];
                    }
                    p[i][j] = s;
                }
            }
        }
    }
    return 0;
}

void BL_FN(query)(const BL_MODEL *mdl, BL_T u, BL_T w, BL_POINT *out)
{
    static const unsigned char up[3] = {0, 3, 6}; /* LL, D, RR */
    static const unsigned char lo[3] = {1, 3, 5}; /* LR, D, RL */
    BL_T bu[BL_DIM], bw[BL_DIM];
    unsigned n = mdl->n, m = mdl->m, fp, ch, i, j, k;
    BL_FN(bernstein)(n, u, bu);
    BL_FN(bernstein)(m, w, bw);
    for (fp = 0; fp < BL_FP; fp++) {
        for (ch = 0; ch < BL_CH; ch++) {
            const BL_T(*p)[BL_DIM] = mdl->p[fp][ch];
            BL_T acc = (BL_T)0;
            for (j = 0; j <= m; j++) {
                BL_T s = (BL_T)0;
                for (i = 0; i <= n; i++) {
                    s += bu[i] * p[i][j];
                }
                acc += bw[j] * s;
            }
            out->v[fp][ch] = acc;
        }
    }
    for (k = 0; k < 3; k++) {
        BL_T umin = out->v[up[0]][2 + k], umax = umin;
        BL_T lmin = out->v[lo[0]][2 + k], lmax = lmin;
        for (i = 1; i < 3; i++) {
            BL_T a = out->v[up[i]][2 + k], b = out->v[lo[i]][2 + k];
            umin = a < umin ? a : umin;
            umax = a > umax ? a : umax;
            lmin = b < lmin ? b : lmin;
            lmax = b > lmax ? b : lmax;
        }
        out->upper_min[k] = umin;
        out->upper_max[k] = umax;
        out->lower_min[k] = lmin;
        out->lower_max[k] = lmax;
    }
}

#undef BL_CAT2
#undef BL_CAT
#undef BL_FN
#undef BL_MODEL
#undef BL_POINT
#undef BL_DATA
