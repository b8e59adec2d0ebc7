#!/bin/bash
# make pkg-cflags: a user's CFLAGS, CPPFLAGS and LDFLAGS reach every host
# compile and link, after (not instead of) the required flags. `make -n -B`
# with a marker in each variable prints every command that would run for
# the programs, the libraries and the given test programs; each line that
# runs $CC must carry all three markers and still -std= and -Werror.
# usage: cflags_check.sh CC TARGET...   (MAKE from the environment)
set -u
. "$(dirname "$0")/../lib/testlib.sh"
tl_init pkg-cflags
cc=$1; shift
marks="-DIT2N_TEST_CFLAGS_MARK -DIT2N_TEST_CPPFLAGS_MARK -LIT2N_TEST_LDFLAGS_MARK"
out=$(${MAKE:-make} --no-print-directory -n -B CFLAGS=-DIT2N_TEST_CFLAGS_MARK \
      CPPFLAGS=-DIT2N_TEST_CPPFLAGS_MARK LDFLAGS=-LIT2N_TEST_LDFLAGS_MARK "$@" 2>&1) ||
  { printf '%s\n' "$out" >&2; TL_FAIL_FAST=1 fail "make -n failed"; }
lines=$(printf '%s\n' "$out" | grep -E "^$cc " || true)
n=$(printf '%s' "$lines" | grep -c . || true)
[ "$n" -ge 20 ] || TL_FAIL_FAST=1 fail "only $n '$cc' command lines in make -n $*"
while IFS= read -r l; do
  for m in $marks -Werror -std=; do
    case " $l" in *" $m"*) ;; *) fail "no $m in: ${l:0:200}"; break;; esac
  done
done <<< "$lines"
[ "$FAILS" != 0 ] || ok "$n $cc compile and link lines carry CFLAGS, CPPFLAGS, LDFLAGS after -std and -Werror"
tl_finish
