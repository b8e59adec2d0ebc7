#!/bin/bash
# make test-install: `make install` into a scratch DESTDIR with
# PREFIX=/opt/it2n, then everything is checked the way a user would meet it:
#   - the layout: every program in PREFIX/bin and PREFIX/sbin has a man page
#     and a bash completion (and every man page and completion a program);
#     it2n, it2nd, it2n-instrument are there; the units are in systemd's
#     unit directory (pkg-config systemd, not under PREFIX) and start
#     PREFIX/sbin/it2nd with /etc/it2n/...; /etc/it2n/it2nd.conf and the
#     .example; the examples the man pages name; libit2n.a, libit2n_proto.a,
#     the headers CMakeLists.txt installs, it2n.pc and it2n-protocol.pc;
#     nothing else is installed;
#   - the installed it2nd accepts the installed it2nd.conf (--check-config),
#     whose state_dir is the unit's StateDirectory; a second `make install`
#     keeps an it2nd.conf the operator changed;
#   - the installed programs run; the man pages format without warnings;
#   - a program built with `pkg-config --cflags --libs it2n-protocol` against
#     the installed tree prints what the installed `it2n eval` prints;
#   - bash-completion finds the completions through XDG_DATA_DIRS=PREFIX/share.
# usage: test_install.sh   (from the repository root; MAKE may name make)
set -euo pipefail
MAKE=${MAKE:-make}
root=$PWD
P=/opt/it2n
d=$(mktemp -d "${TMPDIR:-/tmp}/it2n-install.XXXXXX")
trap 'rm -rf "$d"' EXIT
fail() { echo "test-install: FAIL: $*" >&2; exit 1; }
log=$d/make.log
$MAKE --no-print-directory -s install DESTDIR="$d/root" PREFIX=$P >"$log" 2>&1 ||
  { cat "$log" >&2; fail "make install DESTDIR=... PREFIX=$P"; }
r=$d/root
unitdir=$(pkg-config --variable=systemdsystemunitdir systemd 2>/dev/null || true)
unitdir=${unitdir:-/lib/systemd/system}

# ---- layout ----------------------------------------------------------------
(cd "$r" && find . ! -type d | sed 's|^\./|/|' | sort) >"$d/got"
{
  for f in $P/bin/it2n $P/bin/it2n-instrument $P/sbin/it2nd \
           $unitdir/it2nd.service $unitdir/it2nd@.service \
           /etc/it2n/it2nd.conf /etc/it2n/it2nd.conf.example \
           $P/lib/libit2n.a $P/lib/libit2n_proto.a \
           $P/lib/pkgconfig/it2n.pc $P/lib/pkgconfig/it2n-protocol.pc; do echo "$f"; done
  # each program: its man page and its completion (it2nctl when it is built)
  for f in "$r$P"/bin/* "$r$P"/sbin/*; do
    b=${f##*/}
    if [ "${f%/*}" = "$r$P/sbin" ]; then echo "$P/share/man/man8/$b.8"; else echo "$P/share/man/man1/$b.1"; fi
    echo "$P/share/bash-completion/completions/$b"
    echo "${f#$r}"
  done
  for f in firmware_core/it2n.h protocol/*.h; do echo "$P/include/it2n/${f##*/}"; done
  for f in examples/*.csv examples/firmware/*.[ch] examples/instrument/*.[ch] examples/instrument/README.md; do
    echo "$P/share/doc/it2n/$f"
  done
} | sort -u >"$d/want"
if ! diff -u "$d/want" "$d/got" >"$d/diff"; then
  cat "$d/diff" >&2
  fail "installed files differ from the expected layout (- expected, + installed)"
fi
n_files=$(wc -l <"$d/got")

# the man pages and the examples the CLI's man page names are installed
for ex in $(grep -oE 'examples/[A-Za-z0-9_]+\.csv' cli/it2n.1 | sort -u); do
  [ -s "$r$P/share/doc/it2n/$ex" ] || fail "it2n.1 names $ex, not installed"
done

# ---- units -----------------------------------------------------------------
for u in it2nd.service it2nd@.service; do
  f=$r$unitdir/$u
  grep -q "^ExecStart=$P/sbin/it2nd -c /etc/it2n/" "$f" || fail "$u does not start $P/sbin/it2nd -c /etc/it2n/..."
  ! grep -q /usr/local "$f" || fail "$u still names /usr/local"
done
[ ! -e "$r$P/lib/systemd" ] || fail "units installed under PREFIX, where systemd does not look"

# ---- it2nd.conf ------------------------------------------------------------
conf=$r/etc/it2n/it2nd.conf
grep -q '^state_dir = /var/lib/it2n$' "$conf" || fail "it2nd.conf: state_dir is not /var/lib/it2n"
grep -q '^StateDirectory=it2n$' "$r$unitdir/it2nd.service" || fail "it2nd.service: StateDirectory is not it2n"
"$r$P/sbin/it2nd" -c "$conf" --check-config >"$d/check" 2>&1 ||
  { cat "$d/check" >&2; fail "installed it2nd refuses the installed it2nd.conf"; }
# what docs/packaging.md says it serves: the built-in default
grep -q "(1 listen, 0 rtu, 1 models, 0 links)" "$d/check" || fail "it2nd.conf: $(cat "$d/check")"
for l in 'tcp_listen = 127.0.0.1:1502' '\[model:1\]' 'unit_id = 1' 'preload = paper'; do
  grep -q "^$l\$" "$conf" || fail "it2nd.conf lacks '$l'"
done
echo "; the operator's change" >>"$conf"
cp "$conf" "$d/conf.mine"
$MAKE --no-print-directory -s install DESTDIR="$d/root" PREFIX=$P >"$log" 2>&1 ||
  { cat "$log" >&2; fail "second make install"; }
cmp -s "$conf" "$d/conf.mine" || fail "a second make install overwrote the operator's it2nd.conf"
grep -q "keeping the existing" "$log" || fail "a second make install did not say it kept it2nd.conf"

# ---- programs and man pages ------------------------------------------------
"$r$P/bin/it2n" --help >/dev/null && "$r$P/sbin/it2nd" --version >/dev/null &&
  "$r$P/bin/it2n-instrument" --help >/dev/null || fail "an installed program does not run"
for m in "$r$P"/share/man/man*/*; do
  w=$(LC_ALL=C.UTF-8 MANWIDTH=80 man --warnings -l "$m" 2>&1 >/dev/null) || fail "man -l ${m#$r}"
  [ -z "$w" ] || fail "${m#$r}: $w"
done

# ---- the library through pkg-config ----------------------------------------
export PKG_CONFIG_SYSROOT_DIR=$r PKG_CONFIG_LIBDIR=$r$P/lib/pkgconfig PKG_CONFIG_PATH=
[ "$(pkg-config --modversion it2n)" = "$(sed -n 's/^#define IT2N_CLI_VERSION "\(.*\)"/\1/p' cli/cli.h)" ] ||
  fail "it2n.pc version is not the CLI's"
src=tests/cmake_consumer
${CC:-gcc} -std=c99 -Wall -Wextra -Werror $(pkg-config --cflags it2n-protocol) \
  "$src/host_main.c" "$src/paper_model.c" $(pkg-config --libs it2n-protocol) -o "$d/consumer" ||
  fail "cannot build against the installed it2n-protocol"
{ head -n 1 examples/paper_4x4.csv; grep -E '^[0-9]+,[0-9]+,D,' examples/paper_4x4.csv; } >"$d/d.csv"
"$r$P/bin/it2n" eval "$d/d.csv" --at 0.25,0.75 --decimals 9 | cut -d, -f1-8 >"$d/want.csv"
"$d/consumer" 0.25 0.75 >"$d/got.csv" || fail "the pkg-config consumer failed"
diff -u "$d/want.csv" "$d/got.csv" >&2 || fail "the pkg-config consumer differs from the installed it2n eval"
# A link context's size depends on IT2N_PROTO_WINDOW (16 in this build):
# the .pc file passes it on, and a program compiled with another value
# fails to link instead of overrunning the library's context.
cat >"$d/link_user.c" <<'EOC'
#include <string.h>
#include "it2n_link.h"
static int w(it2n_ostream *s, const uint8_t *p, size_t n) { (void)s; (void)p; (void)n; return 0; }
static int rx(void *a, uint16_t q, const it2n_msg *m) { (void)a; (void)q; (void)m; return 0; }
int main(void)
{
    static it2n_link l;
    it2n_ostream os = { w, NULL };
    it2n_link_cfg c;
    memset(&c, 0, sizeof c);
    c.out = &os;
    c.on_rx = rx;
    c.rto_ms = 100;
    return it2n_link_init(&l, &c) != IT2N_OK || it2n_link_window(&l) != IT2N_PROTO_WINDOW;
}
EOC
${CC:-gcc} -std=c99 -Wall -Wextra -Werror $(pkg-config --cflags it2n-protocol) "$d/link_user.c" \
  $(pkg-config --libs it2n-protocol) -o "$d/link_user" || fail "a link user does not build with the .pc flags"
"$d/link_user" || fail "the link user's window is not the library's"
if ${CC:-gcc} -std=c99 $(pkg-config --cflags it2n-protocol) -UIT2N_PROTO_WINDOW -DIT2N_PROTO_WINDOW=4 \
     "$d/link_user.c" $(pkg-config --libs it2n-protocol) -o "$d/link_user4" 2>"$d/link4.err"; then
  fail "a program compiled with IT2N_PROTO_WINDOW=4 linked against the library built with 16"
fi
grep -q 'it2n_link_init_w4_' "$d/link4.err" || fail "window mismatch: not the expected link error: $(cat "$d/link4.err")"

# ---- bash-completion finds the completions ---------------------------------
for b in "$r$P"/bin/* "$r$P"/sbin/*; do
  b=${b##*/}
  XDG_DATA_DIRS=$r$P/share bash --norc --noprofile -c \
    "source /usr/share/bash-completion/bash_completion && __load_completion $b && complete -p $b" \
    >"$d/spec" 2>&1 || { cat "$d/spec" >&2; fail "bash-completion does not load the completion of $b"; }
  grep -q -- "-F _" "$d/spec" || fail "completion of $b: $(cat "$d/spec")"
done
echo "test-install: ok (PREFIX=$P, DESTDIR=scratch: $n_files files as expected, units in $unitdir," \
  "it2nd.conf kept on reinstall, pkg-config consumer = it2n eval, completions load)"
