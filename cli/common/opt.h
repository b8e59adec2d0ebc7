/*
 * The option parser of it2n and it2nctl: each program declares tables of
 * options (name, argument, range or words, the commands it applies to, help)
 * and this code does the rest the same way for both: argv scanning (options
 * before or after the operands, --name=value, -oVALUE, "--"), range and word
 * checks, "does not apply to CMD", "did you mean", errors as
 *   PROG: what is wrong
 *   Try 'PROG CMD --help'.
 * on stderr (exit status 1), and the option lists of --help.
 */
#ifndef IT2N_CLI_OPT_H
#define IT2N_CLI_OPT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

/* Argument of an option. */
enum {
    CLI_ARG_NONE = 0, /* a flag                                           */
    CLI_ARG_UINT,     /* a decimal number in lo..hi                       */
    CLI_ARG_WORD,     /* one of words ("T|I|F|all"): its index            */
    CLI_ARG_TEXT      /* any text, checked by the program                 */
};

typedef struct cli_opt {
    const char *name;     /* long name without "--"                        */
    char short_name;      /* -X too, or 0                                  */
    unsigned char arg;    /* CLI_ARG_*                                     */
    int id;               /* what cli_opt_next returns for it               */
    unsigned cmds;        /* command bits it applies to; 0: every command   */
    unsigned long lo, hi; /* CLI_ARG_UINT range                            */
    const char *words;    /* CLI_ARG_WORD: '|'-separated                    */
    const char *expect;   /* a refused value: "--NAME 'VALUE': <expect>"    */
    const char *na;       /* after "--NAME does not apply to CMD", or NULL  */
    const char *label;    /* help: "--grid RxC" (NULL: not listed)          */
    const char *help;     /* help: text, '\n' between lines                 */
} cli_opt;

/* One table of options; a program passes several (its own, the shared). */
typedef struct cli_optset {
    const cli_opt *opts;
    size_t count;
} cli_optset;

/* clang-format off */
#define CLI_OPTSET(tab) {(tab), sizeof(tab) / sizeof((tab)[0])}
/* clang-format on */

/* Most tables a parser takes; bits of `seen` per option id. */
#define CLI_OPT_MAX_SETS 4
#define CLI_OPT_MAX_ID 64

typedef struct cli_parser {
    const char *prog; /* "it2n", for messages                        */
    const char *cmd;  /* the command, for messages (NULL: none yet)  */
    unsigned cmdbits; /* the command's bit(s), matched to cli_opt.cmds */
    cli_optset sets[CLI_OPT_MAX_SETS];
    size_t nsets;
    int argc;
    char **argv;
    int next; /* argv index of the next word to read         */
    int nops; /* operands so far: argv[first .. first+nops)  */
    int first;
    bool dashdash;           /* after "--": operands only                   */
    unsigned long long seen; /* bit (1 << id) per option given            */
} cli_parser;

/* What cli_opt_next found: the option, its argument text, and its value
 * (CLI_ARG_UINT: the number; CLI_ARG_WORD: the index in words). */
typedef struct cli_optval {
    const cli_opt *opt;
    const char *text;
    unsigned long num;
} cli_optval;

/* cli_opt_next's answers besides an option id (>= 0). */
enum { CLI_OPT_END = -1, CLI_OPT_ERROR = -2 };

/* Start parsing argv[first..argc) for command cmd (bits cmdbits) with the
 * nsets tables of sets. Operands are moved, in order, to argv[first..]. */
void cli_opt_init(cli_parser *p, const char *prog, const char *cmd, unsigned cmdbits, const cli_optset *sets,
                  size_t nsets, int argc, char **argv, int first);

/* The next option: its id with *v filled, CLI_OPT_END when argv is read
 * (operands: cli_opt_operands), or CLI_OPT_ERROR after printing the usage
 * error (unknown option with a "did you mean", missing or refused
 * argument, an option of another command). */
int cli_opt_next(cli_parser *p, cli_optval *v);

/* The operands (words that are not options or their arguments). */
int cli_opt_operands(const cli_parser *p, char ***ops);

/* True if option id was given. */
bool cli_opt_seen(const cli_parser *p, int id);

/* The option of the tables named `name` (long name, no "--"), or NULL. */
const cli_opt *cli_opt_find(const cli_optset *sets, size_t nsets, const char *name);

/* Print "PROG: " and the printf-style message, then "Try 'PROG CMD
 * --help'." on stderr; returns the usage exit status, 1. cmd NULL: "Try
 * 'PROG --help'." */
int cli_usage_error(const char *prog, const char *cmd, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* The closest of names[0..count) to word, or NULL when none is close
 * enough for a "did you mean": at most 1 edit (insert, delete, change,
 * swap of neighbours) for words up to 4 letters, 2 up to 8, else 3. */
const char *cli_did_you_mean(const char *word, const char *const *names, size_t count);

/* The help list of the options of tab that have a label and apply to
 * cmdbits (0: all): "  LABEL" padded to width, or three spaces when
 * longer, then the help; its further lines indented to width + 2. */
void cli_opt_help(FILE *out, const cli_opt *tab, size_t count, unsigned cmdbits, unsigned width);

#endif /* IT2N_CLI_OPT_H */
