/*
 * it2nctl plot: the live model read back from the daemon (Bezier control
 * nets, or a B-spline's coefficients row by row) into the core's model
 * structs, and drawn with it2n plot's code, once or on every generation.
 */
#include "cli.h"
#include "csv.h"
#include "ctl.h"
#include "ctl_cmds.h"
#include "out.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static unsigned bitlen64(uint64_t v)
{
    unsigned n = 0;
    while (v != 0u) {
        n++;
        v >>= 1;
    }
    return n;
}

/* The live model for plotting: the control nets (Q24) in the core's block
 * floating point, each net's largest point with 30 significant bits. */
static void net_to_model(const ctl_status *st, ctl_net *net, it2n_model *mdl)
{
    unsigned fp, ch, i, j;
    memset(mdl, 0, sizeof(*mdl));
    mdl->n = (uint8_t)st->n;
    mdl->m = (uint8_t)st->m;
    mdl->flags = (uint8_t)st->flags;
    mdl->solved = 1;
    mdl->generation = st->generation;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            uint64_t big = 0;
            int s;
            for (i = 0; i <= st->n; i++) {
                for (j = 0; j <= st->m; j++) {
                    it2n_val v = (*net)[fp][i][j][ch];
                    uint64_t a = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
                    big = a > big ? a : big;
                }
            }
            s = (int)bitlen64(big) - 30;
            mdl->frac[fp][ch] = (int8_t)(IT2N_VAL_FRAC - s);
            for (i = 0; i <= st->n; i++) {
                for (j = 0; j <= st->m; j++) {
                    it2n_val v = (*net)[fp][i][j][ch];
                    int64_t q = s > 0 ? (v + ((int64_t)1 << (s - 1))) >> s : v * ((int64_t)1 << -s);
                    mdl->net[fp][ch][i * (st->m + 1u) + j] = (int32_t)q;
                }
            }
        }
    }
}

/* The live B-spline model for plotting: every net read row by row through
 * the coefficient page, each in block floating point as net_to_model. The
 * coefficients are the map's float32 (24 significant bits): close to the
 * daemon's surface, enough for a drawing. */
static ctl_net g_net;
static it2n_model g_mdl;
static int32_t *g_bcoef;
static it2n_bspline_model g_bmdl;

static int coef_to_model(ctl_session *s, const ctl_status *st)
{
    unsigned rows = st->net_rows, cols = st->net_cols, fp, ch, r, k;
    size_t size = (size_t)rows * cols, words;
    unsigned nch = (st->flags & IT2N_F_Z) ? 6u : 5u;
    it2n_val *v;
    if (s->ops->coef_row == NULL) {
        fprintf(stderr,
                "it2nctl: %s: a B-spline model's coefficients are "
                "read over Modbus (--tcp or --rtu), not --%s\n",
                s->where, s->ops->kind);
        return CTL_EXIT_USAGE;
    }
    if (rows < 4u || cols < 4u || rows != st->n + 3u || cols != st->m + 3u) {
        fprintf(stderr,
                "it2nctl: %s: net of %ux%u for a %ux%u B-spline "
                "model\n",
                s->where, rows, cols, st->n, st->m);
        return CTL_EXIT_DATA;
    }
    words = IT2N_BSPLINE_MODEL_WORDS(st->n, st->m, st->flags);
    free(g_bcoef);
    g_bcoef = malloc(words * sizeof(*g_bcoef));
    v = malloc(size * sizeof(*v));
    if (g_bcoef == NULL || v == NULL) {
        free(v);
        fprintf(stderr, "it2nctl: out of memory for a %ux%u net\n", rows, cols);
        return CTL_EXIT_DATA;
    }
    memset(&g_bmdl, 0, sizeof(g_bmdl));
    g_bmdl.coef = g_bcoef;
    g_bmdl.cap = words;
    g_bmdl.n = (uint16_t)st->n;
    g_bmdl.m = (uint16_t)st->m;
    g_bmdl.flags = (uint8_t)st->flags;
    g_bmdl.solved = 1;
    g_bmdl.generation = st->generation;
    for (fp = 0; fp < IT2N_FP_COUNT; fp++) {
        unsigned slot = (st->flags & IT2N_F_TYPE1) ? 0u : fp, c = 0;
        if ((st->flags & IT2N_F_TYPE1) && fp != IT2N_FP_D) {
            continue;
        }
        for (ch = 0; ch < IT2N_CH_COUNT; ch++) {
            uint64_t big = 0;
            int sh;
            int32_t *net;
            if (ch == IT2N_CH_Z && !(st->flags & IT2N_F_Z)) {
                continue;
            }
            for (r = 0; r < rows; r++) {
                int rc = s->ops->coef_row(s->c, st, fp, ch, r, &v[(size_t)r * cols]);
                if (rc != CTL_EXIT_OK) {
                    free(v);
                    return rc;
                }
            }
            for (k = 0; k < size; k++) {
                uint64_t a = v[k] < 0 ? (uint64_t)0 - (uint64_t)v[k] : (uint64_t)v[k];
                big = a > big ? a : big;
            }
            sh = (int)bitlen64(big) - 30;
            g_bmdl.frac[fp][ch] = (int8_t)(IT2N_VAL_FRAC - sh);
            net = g_bcoef + ((size_t)slot * nch + c) * size;
            for (k = 0; k < size; k++) {
                net[k] = (int32_t)(sh > 0 ? (v[k] + ((int64_t)1 << (sh - 1))) >> sh : v[k] * ((int64_t)1 << -sh));
            }
            c++;
        }
    }
    free(v);
    return CTL_EXIT_OK;
}

/* Draw the model described by st (already read, solved) into o->output. */
static int draw_live(ctl_session *s, const ctl_args *a, const ctl_status *st, const char *output)
{
    cli_opts o = a->o;
    char title[256];
    cli_surface sf;
    int rc;
    memset(&sf, 0, sizeof(sf));
    if (st->kind == 1u) {
        rc = coef_to_model(s, st);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        sf.bsp = &g_bmdl;
    } else {
        rc = s->ops->net(s->c, st, &g_net);
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        net_to_model(st, &g_net, &g_mdl);
        sf.bez = &g_mdl;
    }
    /* The title names the source: no '/' so it is printed whole. */
    snprintf(title, sizeof(title), "it2nd %s %u generation %lu", a->conn.link != NULL ? "model" : "unit",
             a->conn.link != NULL ? a->conn.model : a->conn.unit, (unsigned long)st->generation);
    o.path = title;
    o.output = output;
    return cli_plot(&o, &sf);
}

/* --follow: each drawing goes to a hidden file beside FILE, renamed over it
 * when complete, so a viewer reloading FILE never reads half an image. */
static int follow_plot(ctl_session *s, const ctl_args *a, ctl_status *st)
{
    const char *out = a->o.output, *base = strrchr(out, '/');
    char tmp[4200];
    unsigned drawn = 0;
    int rc;

    base = base ? base + 1 : out;
    snprintf(tmp, sizeof(tmp), "%.*s.%s.part%s", (int)(base - out), out, base, strrchr(base, '.'));
    for (;;) {
        rc = draw_live(s, a, st, tmp);
        if (rc == CTL_EXIT_OK && rename(tmp, out) != 0) {
            fprintf(stderr, "it2nctl: cannot replace %s: %s\n", out, strerror(errno));
            unlink(tmp);
            rc = CTL_EXIT_DATA;
        }
        if (rc != CTL_EXIT_OK) {
            return rc;
        }
        printf("generation %lu: %s\n", (unsigned long)st->generation, out);
        fflush(stdout);
        if (a->count != 0u && ++drawn >= a->count) {
            return cli_finish_output("it2nctl");
        }
        do { /* the next solved generation; pushes in progress skipped */
            rc = ctl_next_generation(s, false, st->generation, st);
            if (rc != CTL_EXIT_OK) {
                return rc;
            }
        } while (st->state != CTL_ST_SOLVED);
    }
}

int ctl_cmd_plot(ctl_session *s, const ctl_args *a)
{
    ctl_status st;
    int rc = ctl_solved_status(s, a, &st);
    if (rc != CTL_EXIT_OK) {
        return rc;
    }
    if (a->o.interval && ctl_out.type1) {
        fprintf(stderr, "it2nctl: %s: --interval needs a type-2 model\n", s->where);
        return CTL_EXIT_DATA;
    }
    return a->follow ? follow_plot(s, a, &st) : draw_live(s, a, &st, a->o.output);
}
