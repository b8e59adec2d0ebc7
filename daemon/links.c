/* links.c — placeholder until the link implementation lands. */
#include "links.h"

int links_start(const struct conf *c) { (void)c; return 0; }
int links_reload(const struct conf *c) { (void)c; return 0; }
void links_release(int commit_ok) { (void)commit_ok; }
void links_stop(void) {}
