/* The table-driven option parser of it2n and it2nctl (opt.h). */
#include "opt.h"

#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

int cli_usage_error(const char *prog, const char *cmd, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "%s: ", prog);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\nTry '%s %s%s--help'.\n", prog, cmd ? cmd : "", cmd ? " " : "");
    return 1;
}

/* Edit distance with swaps of neighbours (optimal string alignment), given
 * up once it exceeds limit; names are short, so rows of 64 suffice. */
static size_t edit_distance(const char *a, const char *b, size_t limit)
{
    size_t la = strlen(a), lb = strlen(b), i, j;
    size_t d[3][64];
    if (la > 62u || lb > 62u) {
        return limit + 1u;
    }
    for (j = 0; j <= lb; j++) {
        d[0][j] = j;
    }
    for (i = 1; i <= la; i++) {
        size_t *cur = d[i % 3u], *prev = d[(i - 1u) % 3u], *prev2 = d[(i + 1u) % 3u];
        cur[0] = i;
        for (j = 1; j <= lb; j++) {
            size_t cost = a[i - 1u] == b[j - 1u] ? 0u : 1u;
            size_t best = prev[j - 1u] + cost;
            if (prev[j] + 1u < best) {
                best = prev[j] + 1u;
            }
            if (cur[j - 1u] + 1u < best) {
                best = cur[j - 1u] + 1u;
            }
            if (i > 1u && j > 1u && a[i - 1u] == b[j - 2u] && a[i - 2u] == b[j - 1u] && prev2[j - 2u] + 1u < best) {
                best = prev2[j - 2u] + 1u;
            }
            cur[j] = best;
        }
    }
    return d[la % 3u][lb];
}

const char *cli_did_you_mean(const char *word, const char *const *names, size_t count)
{
    size_t len = strlen(word), k;
    size_t limit = len <= 4u ? 1u : len <= 8u ? 2u : 3u, best = limit + 1u;
    const char *pick = NULL;
    for (k = 0; k < count; k++) {
        size_t d = edit_distance(word, names[k], limit);
        if (d < best) {
            best = d;
            pick = names[k];
        }
    }
    return pick;
}

void cli_opt_init(cli_parser *p, const char *prog, const char *cmd, unsigned cmdbits, const cli_optset *sets,
                  size_t nsets, int argc, char **argv, int first)
{
    size_t k;
    memset(p, 0, sizeof(*p));
    p->prog = prog;
    p->cmd = cmd;
    p->cmdbits = cmdbits;
    p->nsets = nsets < CLI_OPT_MAX_SETS ? nsets : CLI_OPT_MAX_SETS;
    for (k = 0; k < p->nsets; k++) {
        p->sets[k] = sets[k];
    }
    p->argc = argc;
    p->argv = argv;
    p->next = first;
    p->first = first;
}

const cli_opt *cli_opt_find(const cli_optset *sets, size_t nsets, const char *name)
{
    size_t s, k, len = strcspn(name, "=");
    for (s = 0; s < nsets; s++) {
        for (k = 0; k < sets[s].count; k++) {
            const cli_opt *o = &sets[s].opts[k];
            if (strlen(o->name) == len && strncmp(o->name, name, len) == 0) {
                return o;
            }
        }
    }
    return NULL;
}

static const cli_opt *find_short(const cli_parser *p, char c)
{
    size_t s, k;
    for (s = 0; s < p->nsets; s++) {
        for (k = 0; k < p->sets[s].count; k++) {
            if (p->sets[s].opts[k].short_name == c) {
                return &p->sets[s].opts[k];
            }
        }
    }
    return NULL;
}

/* An error printed (by cli_usage_error): CLI_OPT_ERROR. */
static int fail(int rc)
{
    (void)rc;
    return CLI_OPT_ERROR;
}

/* "unknown option 'WORD'", with the nearest long name when one is close. */
static int unknown(const cli_parser *p, const char *word)
{
    const char *names[128];
    const char *pick = NULL;
    size_t s, k, n = 0;
    if (word[1] == '-') {
        char name[64];
        snprintf(name, sizeof(name), "%.*s", (int)strcspn(word + 2, "="), word + 2);
        for (s = 0; s < p->nsets; s++) {
            for (k = 0; k < p->sets[s].count && n < 128u; k++) {
                names[n++] = p->sets[s].opts[k].name;
            }
        }
        pick = cli_did_you_mean(name, names, n);
    }
    if (pick != NULL) {
        return fail(cli_usage_error(p->prog, p->cmd, "unknown option '%s' (did you mean '--%s'?)", word, pick));
    }
    return fail(cli_usage_error(p->prog, p->cmd, "unknown option '%s'", word));
}

/* How messages name an option: -o for output (as it is written), else
 * --NAME. */
static void shown_name(const cli_opt *o, char *buf, size_t size)
{
    if (o->short_name != 0 && o->short_name != 'h') {
        snprintf(buf, size, "-%c", o->short_name);
    } else {
        snprintf(buf, size, "--%s", o->name);
    }
}

/* Index of text in the '|'-separated words, or -1. */
static int word_index(const char *words, const char *text)
{
    size_t len = strlen(text);
    int k = 0;
    for (;;) {
        size_t w = strcspn(words, "|");
        if (w == len && strncmp(words, text, len) == 0) {
            return k;
        }
        if (words[w] == '\0') {
            return -1;
        }
        words += w + 1u;
        k++;
    }
}

/* The argument's value by the option's type; false if it is refused. */
static bool check_value(const cli_opt *o, cli_optval *v)
{
    if (o->arg == CLI_ARG_UINT) {
        char *end;
        errno = 0;
        if (v->text[0] < '0' || v->text[0] > '9') {
            return false;
        }
        v->num = strtoul(v->text, &end, 10);
        return *end == '\0' && errno == 0 && v->num >= o->lo && v->num <= o->hi;
    }
    if (o->arg == CLI_ARG_WORD) {
        int k = word_index(o->words, v->text);
        v->num = k < 0 ? 0u : (unsigned long)k;
        return k >= 0;
    }
    return true;
}

/* The option word w (argv[p->next - 1]): find it, take its argument, check
 * that it applies and its value. */
static int take_option(cli_parser *p, char *w, cli_optval *v)
{
    const cli_opt *o;
    char shown[64];
    const char *eq = NULL;
    if (w[1] == '-') {
        o = cli_opt_find(p->sets, p->nsets, w + 2);
        eq = strchr(w, '=');
    } else {
        o = find_short(p, w[1]);
        if (o != NULL && o->arg == CLI_ARG_NONE && w[2] != '\0') {
            o = NULL;
        }
    }
    if (o == NULL) {
        return unknown(p, w);
    }
    v->opt = o;
    v->text = NULL;
    v->num = 0;
    if (o->arg != CLI_ARG_NONE) {
        if (eq != NULL) {
            v->text = eq + 1;
        } else if (w[1] != '-' && w[2] != '\0') {
            v->text = w + 2;
        } else if (p->next < p->argc) {
            v->text = p->argv[p->next++];
        } else {
            return fail(cli_usage_error(p->prog, p->cmd, "option '%s' needs an argument", w));
        }
    } else if (eq != NULL) {
        return fail(cli_usage_error(p->prog, p->cmd, "option '--%s' takes no argument", o->name));
    }
    shown_name(o, shown, sizeof(shown));
    if (o->cmds != 0u && (o->cmds & p->cmdbits) == 0u) {
        return fail(cli_usage_error(p->prog, p->cmd, "%s does not apply to %s%s%s", shown, p->cmd ? p->cmd : "",
                                    o->na ? " " : "", o->na ? o->na : ""));
    }
    if (!check_value(o, v)) {
        return fail(cli_usage_error(p->prog, p->cmd, "%s '%s': %s", shown, v->text, o->expect ? o->expect : "refused"));
    }
    if (o->id >= 0 && o->id < CLI_OPT_MAX_ID) {
        p->seen |= 1ull << (unsigned)o->id;
    }
    return o->id;
}

int cli_opt_next(cli_parser *p, cli_optval *v)
{
    while (p->next < p->argc) {
        char *w = p->argv[p->next++];
        int rc;
        if (p->dashdash || w[0] != '-' || w[1] == '\0') {
            p->argv[p->first + p->nops++] = w;
            continue;
        }
        if (strcmp(w, "--") == 0) {
            p->dashdash = true;
            continue;
        }
        rc = take_option(p, w, v);
        return rc;
    }
    return CLI_OPT_END;
}

int cli_opt_operands(const cli_parser *p, char ***ops)
{
    *ops = p->argv + p->first;
    return p->nops;
}

bool cli_opt_seen(const cli_parser *p, int id)
{
    return id >= 0 && id < CLI_OPT_MAX_ID && (p->seen & (1ull << (unsigned)id)) != 0u;
}

void cli_opt_help(FILE *out, const cli_opt *tab, size_t count, unsigned cmdbits, unsigned width)
{
    size_t k;
    for (k = 0; k < count; k++) {
        const cli_opt *o = &tab[k];
        const char *h = o->help;
        size_t len;
        if (o->label == NULL || (cmdbits != 0u && o->cmds != 0u && (o->cmds & cmdbits) == 0u)) {
            continue;
        }
        len = strlen(o->label);
        fprintf(out, "  %s%*s", o->label, len < width ? (int)(width - len) : 3, "");
        for (;;) {
            size_t line = strcspn(h, "\n");
            fprintf(out, "%.*s\n", (int)line, h);
            if (h[line] == '\0' || h[line + 1u] == '\0') {
                break;
            }
            h += line + 1u;
            fprintf(out, "%*s", (int)width + 2, "");
        }
    }
}
