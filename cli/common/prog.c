/* What both programs do before their own options: the command word, its
 * "did you mean", --version, and the help texts, laid out here once from
 * each program's words (cli_prog, cli.h). */
#include "cli.h"

#include <stdio.h>
#include <string.h>

/* Entry k of the command table; each starts with its cli_cmd_text. */
static const cli_cmd_text *cmd_text(const cli_prog *pg, size_t k)
{
    return (const cli_cmd_text *)(const void *)((const char *)pg->cmds + k * pg->stride);
}

static const void *find_cmd(const cli_prog *pg, const char *name)
{
    size_t k;
    for (k = 0; k < pg->ncmds; k++) {
        if (strcmp(cmd_text(pg, k)->name, name) == 0) {
            return cmd_text(pg, k);
        }
    }
    return NULL;
}

/* "unknown command 'X'", with the nearest command when one is close. */
static int unknown_command(const cli_prog *pg, const char *word)
{
    const char *names[32], *near;
    size_t k, n = pg->ncmds < 32u ? pg->ncmds : 32u;
    for (k = 0; k < n; k++) {
        names[k] = cmd_text(pg, k)->name;
    }
    near = cli_did_you_mean(word, names, n);
    if (near != NULL) {
        return cli_usage_error(pg->name, NULL, "unknown command '%s' (did you mean '%s'?)", word, near);
    }
    return cli_usage_error(pg->name, NULL, "unknown command '%s'", word);
}

/* One --version line for `PROG --version` and `PROG CMD --version`. */
static void print_version(const cli_prog *pg)
{
    printf("%s %s (IT2N_MAX_DEGREE %d)\n", pg->name, IT2N_CLI_VERSION, IT2N_MAX_DEGREE);
}

/* The option list that closes both help texts. */
static void put_options(const cli_prog *pg, FILE *out)
{
    fputs(pg->opts_title, out);
    cli_opt_help(out, pg->opts->opts, pg->opts->count, 0u, pg->opts_width);
    fputs(pg->opts_tail, out);
}

/* `PROG --help` (on stderr when the command is missing). */
static void usage_all(const cli_prog *pg, FILE *out)
{
    size_t k;
    fprintf(out, "Usage: %s %s\n%s\n\nCommands:\n", pg->name, pg->synopsis, pg->about);
    for (k = 0; k < pg->ncmds + pg->nmore; k++) {
        const cli_cmd_text *t = k < pg->ncmds ? cmd_text(pg, k) : &pg->more[k - pg->ncmds];
        fprintf(out, "  %-*s %s\n", pg->width, t->name, t->summary);
    }
    fprintf(out, "\n%s'%s COMMAND --help' for details; '%s --version'.\n\n", pg->notes, pg->name, pg->name);
    put_options(pg, out);
}

/* `PROG CMD --help` and `PROG --help CMD`. */
static void usage_cmd(const cli_prog *pg, const void *cmd)
{
    const cli_cmd_text *t = cmd;
    printf("Usage: %s %s%s%s%s%s\n\n%s\n", pg->name, t->name, pg->operands, t->args[0] ? " " : "", t->args, pg->tail,
           t->help);
    put_options(pg, stdout);
}

int cli_builtin_opt(const cli_prog *pg, const void *cmd, int id)
{
    if (id == CLI_OPT_ERROR) {
        return CLI_EXIT_USAGE;
    }
    if (id == CLI_OPT_HELP) {
        usage_cmd(pg, cmd);
        return CLI_EXIT_OK;
    }
    if (id == CLI_OPT_VERSION) {
        print_version(pg);
        return CLI_EXIT_OK;
    }
    return -1;
}

const void *cli_first_word(const cli_prog *pg, int argc, char **argv, int *rc)
{
    const void *c;
    *rc = 0;
    if (argc < 2) {
        usage_all(pg, stderr);
        *rc = 1;
        return NULL;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        if (argc > 2 && (c = find_cmd(pg, argv[2])) != NULL) {
            usage_cmd(pg, c);
        } else {
            usage_all(pg, stdout);
        }
        return NULL;
    }
    if (strcmp(argv[1], "--version") == 0) {
        print_version(pg);
        return NULL;
    }
    if (argv[1][0] == '-' && pg->reorder != NULL && (*rc = pg->reorder(argc, argv)) >= 0) {
        return NULL;
    }
    *rc = 0;
    c = find_cmd(pg, argv[1]);
    if (c == NULL) {
        *rc = unknown_command(pg, argv[1]);
    }
    return c;
}
