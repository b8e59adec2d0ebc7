#!/bin/bash
# mk/format.sh: the code layout of .clang-format over C files (mk/format.mk
# passes FORMAT_FILES, the product code).
#   mk/format.sh check FILE...  each FILE must be exactly what clang-format
#                               writes for it; each one that is not is named
#                               with the first lines of the difference
#   mk/format.sh fix FILE...    rewrite the FILEs in place (make format)
#   mk/format.sh lint FILE...   check, as the lint suite runs it: without
#                               clang-format 14 it prints
#                               "format-check: skip: REASON" and passes
# CLANG_FORMAT (default clang-format) is the program. The style is always
# this tree's .clang-format, named on the command line (--style=file:PATH),
# so a copy of a file outside the tree (tests/lint/format_test.sh) is held
# to the same style. One clang-format process formats copies of all the
# files in a scratch directory (a process per file costs a second each on
# a busy machine); the copies are then compared with the files.
# Exit: 0 formatted (or skipped), 1 some file not formatted, 2 nothing
# checked: no clang-format, no file given, a file missing, clang-format
# failing.
set -u -o pipefail

# The version the style is written for: another major version places some
# breaks differently, so `lint` skips rather than fail on it.
PINNED=14
# Lines of difference shown per file.
SHOW=12

mode=${1-}
shift || true
cf=${CLANG_FORMAT:-clang-format}
root=$(cd "$(dirname "$0")/.." && pwd)
style=$root/.clang-format

die() {
    echo "format-check: $*" >&2
    exit 2
}

case $mode in
check | fix | lint) ;;
*) die "usage: mk/format.sh check|fix|lint FILE... (mode '$mode' unknown)" ;;
esac

if ! command -v "$cf" >/dev/null 2>&1; then
    if [ "$mode" = lint ]; then
        echo "format-check: skip: clang-format not installed"
        exit 0
    fi
    die "$cf not found: install clang-format $PINNED (make deps, or apt-get install clang-format)"
fi
version=$("$cf" --version 2>/dev/null | sed -n 's/.*clang-format version \([0-9]*\).*/\1/p')
if [ "$version" != "$PINNED" ]; then
    if [ "$mode" = lint ]; then
        echo "format-check: skip: $cf is version ${version:-unknown}, .clang-format is checked with $PINNED"
        exit 0
    fi
    echo "format-check: note: $cf is version ${version:-unknown}; .clang-format is written for $PINNED" >&2
fi
[ -f "$style" ] || die "$style missing"
[ $# -gt 0 ] || die "no files given (mk/format.mk: FORMAT_FILES is empty)"
for f in "$@"; do
    [ -f "$f" ] || die "$f: no such file (mk/format.mk lists it)"
done

if [ "$mode" = fix ]; then
    "$cf" --style=file:"$style" -i "$@" || die "$cf failed (nothing or part rewritten)"
    exit 0
fi

tmp=$(mktemp -d "${TMPDIR:-/tmp}/it2n-format.XXXXXX") || die "cannot create a scratch directory"
trap 'rm -rf "$tmp"' EXIT
# Copy k of FILE is $tmp/k/NAME: the same name (clang-format picks the
# language by it), whatever path FILE was given by.
copies=()
k=0
for f in "$@"; do
    c=$tmp/$k/$(basename "$f")
    mkdir -p "$tmp/$k" || die "cannot create $tmp/$k"
    cp "$f" "$c" || die "cannot copy $f to $tmp"
    copies+=("$c")
    k=$((k + 1))
done
"$cf" --style=file:"$style" -i "${copies[@]}" || die "$cf failed on the files above"

bad=0
k=0
for f in "$@"; do
    c=${copies[$k]}
    k=$((k + 1))
    if ! cmp -s "$f" "$c"; then
        bad=$((bad + 1))
        echo "format-check: $f is not formatted; first differences (- as written, + as clang-format writes it):"
        diff -u "$f" "$c" | sed -n "3,$((SHOW + 2))p" | sed 's/^/    /'
    fi
done
if [ $bad -gt 0 ]; then
    echo "format-check: $bad of $# files not formatted: run \`make format\` and commit the result" \
        "(or fence a table the formatter mangles with /* clang-format off */ ... /* clang-format on */)"
    exit 1
fi
echo "format-check: $# files formatted as .clang-format says"
