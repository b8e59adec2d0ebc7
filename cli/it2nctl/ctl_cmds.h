/*
 * it2nctl's commands (ctl_cmds.c, ctl_live.c) and what the option parsing
 * of ctl_main.c hands them: the parsed command line and an open session.
 */
#ifndef IT2N_CTL_CMDS_H
#define IT2N_CTL_CMDS_H

#include "cli.h"
#include "ctl.h"
#include "out.h"

struct ctl_args;
struct ctl_session;

/* A command: its name and help texts, option bits (CLI_O_*, O_*) and
 * what runs it once the daemon is reached. */
typedef struct ctl_cmd {
    cli_cmd_text t;
    unsigned opts;
    int (*run)(struct ctl_session *s, const struct ctl_args *a);
} ctl_cmd;

typedef struct ctl_args {
    const ctl_cmd *cmd;
    cli_opts o; /* output options as it2n's            */
    ctl_conn_opts conn;
    unsigned count;  /* watch/plot --count, 0 = forever      */
    bool incomplete; /* watch --incomplete                   */
    bool follow;     /* plot --follow                        */
} ctl_args;

typedef struct ctl_session {
    void *c;
    const ctl_ops *ops;
    const char *where; /* for messages */
    char wbuf[200];
} ctl_session;

/* The commands; each returns an exit status (CTL_EXIT_*). */
int ctl_cmd_status(ctl_session *s, const ctl_args *a);
int ctl_cmd_push(ctl_session *s, const ctl_args *a);
int ctl_cmd_eval(ctl_session *s, const ctl_args *a);
int ctl_cmd_locate(ctl_session *s, const ctl_args *a);
int ctl_cmd_net(ctl_session *s, const ctl_args *a);
int ctl_cmd_sample(ctl_session *s, const ctl_args *a);
int ctl_cmd_watch(ctl_session *s, const ctl_args *a);
int ctl_cmd_plot(ctl_session *s, const ctl_args *a);

/* push: read and solve DATA.csv (a->o.path) as it2n does, before the
 * daemon is contacted. */
int ctl_load(const cli_opts *o);

/* The model's status, which must be solved for a query (message
 * otherwise); also sets the rows' z and type for the output. */
int ctl_solved_status(ctl_session *s, const ctl_args *a, ctl_status *st);

/* Wait for the next generation after gen worth a row or a drawing (every:
 * each one, a push's too). */
int ctl_next_generation(ctl_session *s, bool every, uint32_t gen, ctl_status *st);

/* The rows' options and the model's z and type (ctl_solved_status). */
extern cli_out ctl_out;

#endif /* IT2N_CTL_CMDS_H */
