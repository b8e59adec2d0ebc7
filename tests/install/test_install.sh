#!/bin/bash
# make pkg-install: `make install` into a scratch DESTDIR with
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
#   - a program built with `pkg-config --cflags --libs it2n-regmap` encodes
#     and looks up through the installed register map library;
#   - ABI guards: a program calling every entry point whose structs a build
#     option sizes links and runs with the .pc flags, and fails to link
#     (naming each entry point with its options) with any other window,
#     payload, reorder, IT2N_MAX_DEGREE or IT2N_CHORD, or without the flags;
#   - bash-completion finds the completions through XDG_DATA_DIRS=PREFIX/share.
# usage: test_install.sh   (from the repository root; MAKE may name make)
set -euo pipefail
MAKE=${MAKE:-make}
root=$PWD
P=/opt/it2n
. "$(dirname "$0")/../lib/testlib.sh"
TL_FAIL_FAST=1
tl_init pkg-install it2n-install
d=$T
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
           $P/lib/libit2n.a $P/lib/libit2n_proto.a $P/lib/libit2n_regmap.a \
           $P/lib/pkgconfig/it2n.pc $P/lib/pkgconfig/it2n-protocol.pc $P/lib/pkgconfig/it2n-regmap.pc; do echo "$f"; done
  # each program: its man page and its completion (it2nctl when it is built)
  for f in "$r$P"/bin/* "$r$P"/sbin/*; do
    b=${f##*/}
    if [ "${f%/*}" = "$r$P/sbin" ]; then echo "$P/share/man/man8/$b.8"; else echo "$P/share/man/man1/$b.1"; fi
    echo "$P/share/bash-completion/completions/$b"
    echo "${f#$r}"
  done
  for f in firmware_core/it2n.h protocol/*.h regmap/*.h; do echo "$P/include/it2n/${f##*/}"; done
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
for ex in $(grep -oE 'examples/[A-Za-z0-9_]+\.csv' cli/it2n/it2n.1 | sort -u); do
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
[ "$(pkg-config --modversion it2n)" = "$(cat VERSION)" ] ||
  fail "it2n.pc version is not the CLI's"
src=tests/cmake_consumer
${CC:-gcc} -std=c99 -Wall -Wextra -Werror $(pkg-config --cflags it2n-protocol) \
  "$src/host_main.c" "$src/paper_model.c" $(pkg-config --libs it2n-protocol) -o "$d/consumer" ||
  fail "cannot build against the installed it2n-protocol"
{ head -n 1 examples/paper_4x4.csv; grep -E '^[0-9]+,[0-9]+,D,' examples/paper_4x4.csv; } >"$d/d.csv"
"$r$P/bin/it2n" eval "$d/d.csv" --at 0.25,0.75 --decimals 9 | cut -d, -f1-8 >"$d/want.csv"
"$d/consumer" 0.25 0.75 >"$d/got.csv" || fail "the pkg-config consumer failed"
diff -u "$d/want.csv" "$d/got.csv" >&2 || fail "the pkg-config consumer differs from the installed it2n eval"
# The register map library on its own (it depends on nothing else).
${CC:-gcc} -std=c99 -Wall -Wextra -Werror $(pkg-config --cflags it2n-regmap) \
  tests/install/regmap_user.c $(pkg-config --libs it2n-regmap) -o "$d/regmap_user" ||
  fail "cannot build against the installed it2n-regmap"
got=$("$d/regmap_user") || fail "the it2n-regmap consumer failed"
[ "$got" = "0000 3fc0 sample_grid 5000" ] || fail "the it2n-regmap consumer printed '$got', not '0000 3fc0 sample_grid 5000'"
# ABI guards: every entry point whose structs are sized by a build option
# is named after the options (it2n.h, it2n_proto.h). The library here is
# built with window 16 (the .pc file passes it on); abi_user calls each
# such entry point. With the .pc flags it links and runs; compiled with
# any other value of any option (or without the .pc flags, as a plain
# -I/-L user of the installed tree would) it must fail to link, and the
# linker must name every guarded entry point with the values it asked for.
cc_abi() { # $1 = output, rest = extra flags; the linker's errors in $1.err
  local out=$1; shift
  ${CC:-gcc} -std=c99 -Wall -Wextra -Werror "$@" tests/cmake_consumer/abi_user.c \
    -L"$r$P/lib" -lit2n_proto -lit2n -o "$out" 2>"$out.err"
}
abi_names() { # $1 = core suffix, $2 = protocol suffix ("-": that library matches)
  [ "$1" = - ] || for f in it2n_dataset_init it2n_model_init; do echo "${f}_abi_$1"; done
  [ "$2" = - ] || for f in it2n_msg_pack it2n_msg_unpack it2n_proto_vector it2n_frame_decoder_init \
           it2n_link_init it2n_inst_open; do echo "${f}_abi_$2"; done
}
pc_cflags=$(pkg-config --cflags it2n-protocol)
cc_abi "$d/abi_ok" $pc_cflags || { cat "$d/abi_ok.err" >&2; fail "abi_user does not build with the .pc flags"; }
"$d/abi_ok" >"$d/abi_ok.out" || fail "abi_user built with the .pc flags: $(cat "$d/abi_ok.out")"
grep -q 'window 16, payload 1024' "$d/abi_ok.out" || fail "the .pc flags do not give window 16: $(cat "$d/abi_ok.out")"
n_abi=0
abi_refused() { # $1 = label, $2 = core suffix, $3 = protocol suffix, rest = flags
  local label=$1 core=$2 proto=$3 out=$d/abi_$n_abi; shift 3
  n_abi=$((n_abi + 1))
  if cc_abi "$out" "$@"; then
    fail "ABI guard: $label linked against the installed library (window 16, default options)"
  fi
  for s in $(abi_names "$core" "$proto"); do
    grep -q "undefined reference to .$s'" "$out.err" ||
      fail "ABI guard: $label: the link error does not name $s: $(head -c 2000 "$out.err")"
  done
  [ "$(grep -c 'undefined reference' "$out.err")" = "$(abi_names "$core" "$proto" | wc -l)" ] ||
    fail "ABI guard: $label: other link errors than the guarded names: $(head -c 2000 "$out.err")"
}
abi_refused "-I/-L without the .pc flags (window 4)" - window4_payload1024_reorder1_degree7 \
  -I"$r$P/include/it2n"
abi_refused "IT2N_MAX_DEGREE=3" degree3_chord1 window16_payload1024_reorder1_degree3 \
  $pc_cflags -DIT2N_MAX_DEGREE=3
abi_refused "IT2N_CHORD=0" degree7_chord0 - \
  $pc_cflags -DIT2N_CHORD=0
abi_refused "IT2N_PROTO_MAX_PAYLOAD=512" - window16_payload512_reorder1_degree7 \
  $pc_cflags -DIT2N_PROTO_MAX_PAYLOAD=512
abi_refused "IT2N_PROTO_RX_REORDER=0" - window16_payload1024_reorder0_degree7 \
  $pc_cflags -DIT2N_PROTO_RX_REORDER=0
abi_refused "IT2N_PROTO_WINDOW=4" - window4_payload1024_reorder1_degree7 \
  $pc_cflags -UIT2N_PROTO_WINDOW -DIT2N_PROTO_WINDOW=4

# ---- docs/packaging.md lists what is installed ------------------------------
want_h=$(grep '^| headers ' docs/packaging.md | grep -o '`[a-z0-9_]*\.h`' | tr -d '`' | sort | tr '\n' ' ')
got_h=$(ls "$r$P/include/it2n" | sort | tr '\n' ' ')
[ "$want_h" = "$got_h" ] || fail "docs/packaging.md lists headers '$want_h', make install installs '$got_h'"
for lib in libit2n.a libit2n_proto.a libit2n_regmap.a; do
  [ -f "$r$P/lib/$lib" ] && grep -q "\`$lib\`" docs/packaging.md || fail "docs/packaging.md and the installed $lib disagree"
done

# ---- names: the libraries export only their own prefix -----------------------
# Every global symbol of the installed libraries is it2n_ (public: declared
# in an installed header, the ABI-tagged names by their base name) or
# it2n__ (internal); nothing lands in a user's firmware under another name.
n_sym=0
for lib in "$r$P"/lib/libit2n.a "$r$P"/lib/libit2n_proto.a "$r$P"/lib/libit2n_regmap.a; do
  while read -r sym; do
    n_sym=$((n_sym + 1))
    case $sym in
      it2n__*) ;;
      it2n_*) base=${sym%%_abi_*}
              grep -qw -- "$base" "$r$P"/include/it2n/*.h ||
                fail "${lib##*/}: $sym has the public prefix but no installed header declares $base (internal: it2n__)" ;;
      *) fail "${lib##*/}: global symbol $sym lacks the it2n_ prefix" ;;
    esac
  done < <(nm -g --defined-only "$lib" | awk 'NF == 3 && $2 != "V" && $2 != "W" {print $3}' | sort -u)
done
[ "$n_sym" -gt 40 ] || fail "only $n_sym global symbols in the installed libraries"

# ---- bash-completion finds the completions ---------------------------------
for b in "$r$P"/bin/* "$r$P"/sbin/*; do
  b=${b##*/}
  XDG_DATA_DIRS=$r$P/share bash --norc --noprofile -c \
    "source /usr/share/bash-completion/bash_completion && __load_completion $b && complete -p $b" \
    >"$d/spec" 2>&1 || { cat "$d/spec" >&2; fail "bash-completion does not load the completion of $b"; }
  grep -q -- "-F _" "$d/spec" || fail "completion of $b: $(cat "$d/spec")"
done
echo "pkg-install: ok (PREFIX=$P, DESTDIR=scratch: $n_files files as expected, units in $unitdir," \
  "it2nd.conf kept on reinstall, pkg-config consumer = it2n eval, ABI guards: matching options link and run," \
  "$n_abi mismatches refused at link time, $n_sym global symbols all it2n_ (public, declared) or it2n__, completions load)"
