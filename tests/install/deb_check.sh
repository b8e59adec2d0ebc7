#!/bin/bash
# make deb-check: the packages `make deb` built, checked the way an
# installation meets them (without installing them on this machine: the
# .debs are unpacked into a scratch directory).
#   - dpkg-deb -I: name, version (= debian/changelog = VERSION), the
#     architecture, the shared libraries it2nd links (shlibs), conffiles
#     (/etc/it2n/it2nd.conf and the .example), maintainer scripts that
#     enable and start it2nd.service (dh_installsystemd) and leave the
#     it2nd@ template alone;
#   - dpkg-deb -c: it2n + libit2n-dev hold exactly what
#     `make install PREFIX=/usr LIBDIR=/usr/lib/TRIPLET` installs (man pages
#     gzipped, plus the copyright and changelog), each file in one package,
#     the libraries, headers and .pc files in libit2n-dev; every program has
#     a man page and a bash completion; the units start /usr/sbin/it2nd,
#     which is in the package;
#   - unpacked: it2n checks the example the man page names, it2nd accepts
#     its conffile, a program built with pkg-config against libit2n-dev
#     prints what the packaged it2n prints;
#   - lintian (-I --pedantic) on the .changes and the source package (.dsc):
#     no error, and the warnings
#     and notes are exactly those listed in docs/packaging.md (the block
#     between the lintian markers; DEB_CHECK_UPDATE=1 rewrites it).
# usage: deb_check.sh DEB_OUT [contents|lintian]   (from the repository root;
# MAKE may name make). Without PART, both: make test runs them as two suites,
# deb-contents (its make install runs alone) and deb-lintian (no make in it:
# it shares the machine).
set -euo pipefail
MAKE=${MAKE:-make}
out=$1
part=${2:-all}
case $part in all | contents | lintian) ;; *) echo "deb_check.sh: PART is contents or lintian, not '$part'" >&2; exit 2 ;; esac
doc=docs/packaging.md
. "$(dirname "$0")/../lib/testlib.sh"
TL_FAIL_FAST=1
tl_init deb-check it2n-debcheck
w=$T

ver=$(dpkg-parsechangelog -l debian/changelog -S Version)
cli_ver=$(cat VERSION)
[ "$ver" = "$cli_ver" ] || fail "debian/changelog says $ver, VERSION $cli_ver"
arch=$(dpkg --print-architecture)
triplet=$(dpkg-architecture -qDEB_HOST_MULTIARCH)
main=$out/it2n_${ver}_$arch.deb
dev=$out/libit2n-dev_${ver}_$arch.deb
changes=$out/it2n_${ver}_$arch.changes
for f in "$main" "$dev" "$changes"; do [ -s "$f" ] || fail "$f missing (make deb)"; done

# The package contents (PART contents, or both); not indented, to keep the
# history of the lines readable.
if [ "$part" != lintian ]; then

# ---- dpkg-deb -I -------------------------------------------------------------
field() { dpkg-deb -f "$1" "$2"; }
[ "$(field "$main" Package)" = it2n ] && [ "$(field "$dev" Package)" = libit2n-dev ] || fail "package names"
for f in "$main" "$dev"; do
  [ "$(field "$f" Version)" = "$ver" ] || fail "$f: Version is not $ver"
  [ "$(field "$f" Architecture)" = "$arch" ] || fail "$f: Architecture is not $arch"
done
deps=$(field "$main" Depends)
for lib in libc6 libmodbus5 libinih1 libusb-1.0-0 libmicrohttpd12; do
  grep -qE "(^|, )$lib( |,|$)" <<<"$deps" || fail "it2n Depends lacks $lib: $deps"
done
[ "$(field "$dev" Multi-Arch)" = same ] || fail "libit2n-dev is not Multi-Arch: same"
dpkg-deb -e "$main" "$w/control"
diff <(sort "$w/control/conffiles") <(printf '%s\n' /etc/it2n/it2nd.conf /etc/it2n/it2nd.conf.example) \
  >/dev/null || fail "conffiles: $(tr '\n' ' ' <"$w/control/conffiles")"
grep -q "deb-systemd-helper enable 'it2nd.service'" "$w/control/postinst" ||
  fail "postinst does not enable it2nd.service"
grep -q "deb-systemd-invoke \$_dh_action 'it2nd.service'" "$w/control/postinst" ||
  fail "postinst does not start it2nd.service"
grep -q "deb-systemd-invoke stop 'it2nd.service'" "$w/control/prerm" || fail "prerm does not stop it2nd.service"
grep -q "deb-systemd-helper purge 'it2nd.service'" "$w/control/postrm" || fail "postrm does not purge it2nd.service"
! grep -q "it2nd@" "$w/control/postinst" || fail "postinst enables the it2nd@ template"
say "dpkg-deb -I: it2n and libit2n-dev $ver ($arch), Depends: $deps; conffiles: it2nd.conf and .example; it2nd.service enabled and started by postinst"

# ---- dpkg-deb -c against make install ------------------------------------------
files() { dpkg-deb -c "$1" | awk '$1 !~ /^d/ {print $6}' | sed 's|^\./|/|' | sort; }
files "$main" >"$w/main"
files "$dev" >"$w/dev"
dup=$(sort "$w/main" "$w/dev" | uniq -d)
[ -z "$dup" ] || fail "in both packages: $dup"
unitdir=$(pkg-config --variable=systemdsystemunitdir systemd 2>/dev/null || true)
$MAKE --no-print-directory -s install DESTDIR="$w/inst" PREFIX=/usr LIBDIR=/usr/lib/$triplet \
  UNITDIR="${unitdir:-/lib/systemd/system}" >"$w/inst.log" 2>&1 || { cat "$w/inst.log" >&2; fail "make install"; }
{
  (cd "$w/inst" && find . ! -type d | sed 's|^\./|/|') | sed -E 's|^(/usr/share/man/.*)$|\1.gz|'
  for p in it2n libit2n-dev; do echo "/usr/share/doc/$p/copyright"; echo "/usr/share/doc/$p/changelog.gz"; done
} | sort >"$w/want"
if ! diff -u "$w/want" <(sort "$w/main" "$w/dev") >"$w/diff"; then
  cat "$w/diff" >&2
  fail "the packages differ from make install (- make install, + packages)"
fi
bad=$(grep -vE "^/usr/(include/it2n/[^/]+\.h|lib/$triplet/(lib[a-z0-9_]+\.a|pkgconfig/[a-z0-9-]+\.pc)|share/doc/libit2n-dev/.*)$" "$w/dev" || true)
[ -z "$bad" ] || fail "libit2n-dev holds $bad"
for f in /usr/lib/$triplet/libit2n.a /usr/lib/$triplet/libit2n_proto.a /usr/include/it2n/it2n.h \
         /usr/include/it2n/it2n_proto.h /usr/lib/$triplet/pkgconfig/it2n.pc /usr/lib/$triplet/pkgconfig/it2n-protocol.pc; do
  grep -qx "$f" "$w/dev" || fail "libit2n-dev lacks $f"
done
progs=$(grep -E '^/usr/s?bin/' "$w/main" | sed 's|.*/||' | sort | tr '\n' ' ')
for p in it2n it2nd it2n-instrument; do [[ " $progs " == *" $p "* ]] || fail "it2n lacks the program $p"; done
for p in $progs; do
  grep -qE "^/usr/share/man/man[18]/$p\.[18]\.gz$" "$w/main" || fail "no man page for $p"
  grep -qx "/usr/share/bash-completion/completions/$p" "$w/main" || fail "no bash completion for $p"
done
for c in $(grep '^/usr/share/bash-completion/completions/' "$w/main" | sed 's|.*/||'); do
  [[ " $progs " == *" $c "* ]] || fail "completion $c belongs to no program of the package"
done
say "dpkg-deb -c: $(wc -l <"$w/main") + $(wc -l <"$w/dev") files = make install (PREFIX=/usr) + copyright/changelog; programs: $progs(each with a man page and a completion)"

# ---- unpacked ----------------------------------------------------------------
r=$w/root
dpkg-deb -x "$main" "$r"
dpkg-deb -x "$dev" "$r"
for u in it2nd.service it2nd@.service; do
  f=$(find "$r" -path "*/systemd/system/$u")
  [ -n "$f" ] || fail "$u not in the package"
  e=$(sed -n 's/^ExecStart=\([^ ]*\) .*/\1/p' "$f")
  [ "$e" = /usr/sbin/it2nd ] && [ -x "$r$e" ] || fail "$u: ExecStart=$e is not the packaged /usr/sbin/it2nd"
  grep -q "^ExecStart=/usr/sbin/it2nd -c /etc/it2n/" "$f" || fail "$u does not read /etc/it2n/"
done
ex=$(grep -oE 'examples/[A-Za-z0-9_]+\.csv' cli/it2n/it2n.1 | sort -u)
for e in $ex; do
  "$r/usr/bin/it2n" check "$r/usr/share/doc/it2n/$e" >"$w/check" 2>&1 || { cat "$w/check" >&2; fail "it2n check $e"; }
done
"$r/usr/sbin/it2nd" -c "$r/etc/it2n/it2nd.conf" --check-config >"$w/check" 2>&1 ||
  { cat "$w/check" >&2; fail "the packaged it2nd refuses its it2nd.conf"; }
grep -q '^state_dir = /var/lib/it2n$' "$r/etc/it2n/it2nd.conf" || fail "it2nd.conf: state_dir is not /var/lib/it2n"
export PKG_CONFIG_SYSROOT_DIR=$r PKG_CONFIG_LIBDIR=$r/usr/lib/$triplet/pkgconfig PKG_CONFIG_PATH=
[ "$(pkg-config --modversion it2n-protocol)" = "$ver" ] || fail "it2n-protocol.pc version"
src=tests/cmake_consumer
${CC:-gcc} -std=c99 -Wall -Wextra -Werror $(pkg-config --cflags it2n-protocol) \
  "$src/host_main.c" "$src/paper_model.c" $(pkg-config --libs it2n-protocol) -o "$w/consumer" ||
  fail "cannot build against libit2n-dev with pkg-config"
ex1=$r/usr/share/doc/it2n/examples/paper_4x4.csv
{ head -n 1 "$ex1"; grep -E '^[0-9]+,[0-9]+,D,' "$ex1"; } >"$w/d.csv"
"$r/usr/bin/it2n" eval "$w/d.csv" --at 0.25,0.75 --decimals 9 | cut -d, -f1-8 >"$w/want.csv"
"$w/consumer" 0.25 0.75 >"$w/got.csv" || fail "the libit2n-dev consumer failed"
diff -u "$w/want.csv" "$w/got.csv" >&2 || fail "the libit2n-dev consumer differs from the packaged it2n eval"
say "unpacked: it2n check $(echo $ex | tr '\n' ' ')ok, it2nd accepts /etc/it2n/it2nd.conf, pkg-config consumer of libit2n-dev = it2n eval"
fi
[ "$part" != contents ] || exit 0

# ---- lintian ------------------------------------------------------------------
dsc=$out/it2n_$ver.dsc
[ -s "$dsc" ] || fail "$dsc missing (make deb)"
lintian -I --pedantic --tag-display-limit 0 "$changes" "$dsc" >"$out/lintian.txt" 2>"$w/lintian.err" || true
if grep -vE '^(running with root privileges is not recommended!|A future release.*)$' "$w/lintian.err" | grep -q .; then
  cat "$w/lintian.err" >&2; fail "lintian did not run cleanly"
fi
grep -E '^[EWIPX]: ' "$out/lintian.txt" | sort -u >"$w/tags" || true
errors=$(grep -c '^E: ' "$w/tags" || true)
[ "$errors" = 0 ] || { grep '^E: ' "$w/tags" >&2; fail "lintian: $errors errors"; }
nw=$(grep -c '^W: ' "$w/tags" || true)
ni=$(grep -c '^[IPX]: ' "$w/tags" || true)
# the documented list: one "    X: package: tag [context]" line per tag
block() { sed -n '/<!-- lintian:begin -->/,/<!-- lintian:end -->/p' "$doc" | grep -E '^    [EWIPX]: ' | sed 's/^    //'; }
if [ "${DEB_CHECK_UPDATE:-0}" = 1 ]; then
  python3 - "$doc" "$w/tags" <<'EOF'
import re, sys
doc, tags = sys.argv[1], open(sys.argv[2]).read().split("\n")
lines = [l for l in tags if l]
body = "\n".join("    " + l for l in lines) if lines else "    (none)"
text = open(doc).read()
new = re.sub(r"(<!-- lintian:begin -->\n).*?(\n<!-- lintian:end -->)",
             lambda m: m.group(1) + "\n" + body + "\n" + m.group(2), text, flags=re.S)
if new == text and "<!-- lintian:begin -->" not in text:
    sys.exit("deb-check: no lintian markers in " + doc)
open(doc, "w").write(new)
EOF
  say "$doc: lintian list rewritten"
fi
if ! diff -u <(block) "$w/tags" >"$w/ldiff"; then
  cat "$w/ldiff" >&2
  fail "lintian's warnings and notes differ from $doc (- documented, + lintian); make deb-check DEB_CHECK_UPDATE=1 rewrites the list"
fi
say "lintian $(lintian --version | awk '{print $2}') -I --pedantic: errors 0, warnings $nw, notes $ni, as listed in $doc (full output: $out/lintian.txt)"
