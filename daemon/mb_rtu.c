/* mb_rtu.c — placeholder. */
#include "mb_rtu.h"

int mb_rtu_start(const struct conf *c, const struct mb_opts *o) { (void)c; (void)o; return 0; }
int mb_rtu_reload(const struct conf *c, const struct mb_opts *o) { (void)c; (void)o; return 0; }
void mb_rtu_release(int commit_ok) { (void)commit_ok; }
void mb_rtu_stop(void) {}
