/*
 * it2n's commands (commands.c), what main.c's option parsing hands over:
 * the module prefix of cli/it2n is cmd_ (cli/common is cli_, cli/it2nctl
 * ctl_; tests/lint/names.py).
 */
#ifndef IT2N_CLI_COMMANDS_H
#define IT2N_CLI_COMMANDS_H

#include "cli.h"

/* Run the subcommand in o; returns an exit status. */
int cmd_run(const cli_opts *o);

#endif
