#!/bin/bash
# format_test.sh: mk/format.sh, the command under `make format-check`,
# `make format` and the lint suite, can fail. A product file formatted by
# clang-format passes; copies with a mangled indentation and a misplaced
# brace fail, each named with the offending line, the formatted copy not;
# `fix` restores them; bad calls (no clang-format, no file, a missing
# file) stop with exit 2 and a message, and in lint mode a missing
# clang-format prints "format-check: skip: ..." (never ok).
#   tests/lint/format_test.sh [PRODUCT-FILE]   (default protocol/it2n_crc32.c)
. "$(dirname "$0")/../lib/testlib.sh"
tl_init format-test
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
FMT=$ROOT/mk/format.sh
SRC=${1:-$ROOT/protocol/it2n_crc32.c}
CF=${CLANG_FORMAT:-clang-format}

if ! command -v "$CF" >/dev/null 2>&1; then
    skip "clang-format not installed"
    exit 0
fi
v=$("$CF" --version | sed -n 's/.*clang-format version \([0-9]*\).*/\1/p')
if [ "$v" != 14 ]; then
    skip "$CF is version ${v:-unknown}, .clang-format is checked with 14"
    exit 0
fi

# good.c: the product file as clang-format writes it (whatever the tree's
# state); bad_indent.c: one body line indented by 2 instead of 4;
# bad_brace.c: a function's brace moved up to its signature.
"$CF" --style=file:"$ROOT/.clang-format" "$SRC" > "$T/good.c" || fail "clang-format on $SRC"
line=$(grep -n -m1 '^    [a-z]' "$T/good.c" | cut -d: -f1)
[ -n "$line" ] || fail "$SRC: no line indented by 4 to mangle"
sed "${line}s/^    /  /" "$T/good.c" > "$T/bad_indent.c"
mangled=$(sed -n "${line}p" "$T/bad_indent.c")
brace=$(grep -n -m1 '^{$' "$T/good.c" | cut -d: -f1)
[ -n "$brace" ] || fail "$SRC: no function brace to move"
awk -v b="$brace" 'NR == b - 1 { held = $0; next } NR == b { print held " {"; next } { print }' \
    "$T/good.c" > "$T/bad_brace.c"
cmp -s "$T/good.c" "$T/bad_indent.c" && fail "the mangling changed nothing"
cmp -s "$T/good.c" "$T/bad_brace.c" && fail "the brace move changed nothing"

out=$("$FMT" check "$T/good.c" 2>&1)
rc=$?
[ $rc = 0 ] && ok "a formatted copy of ${SRC#"$ROOT"/} passes" || fail "formatted copy: exit $rc: $out"

out=$("$FMT" check "$T/good.c" "$T/bad_indent.c" "$T/bad_brace.c" 2>&1)
rc=$?
[ $rc = 1 ] && ok "mangled copies: exit 1" || fail "mangled copies: exit $rc (want 1): $out"
grep -q "^format-check: $T/bad_indent.c is not formatted" <<<"$out" &&
    grep -q "^format-check: $T/bad_brace.c is not formatted" <<<"$out" &&
    ok "both mangled files named" || fail "a mangled file not named: $out"
grep -q "good.c is not formatted" <<<"$out" && fail "the formatted copy named too: $out"
grep -qF -- "    -$mangled" <<<"$out" && ok "the mangled line shown: '$mangled'" ||
    fail "the mangled line '$mangled' not among the differences: $out"
grep -q "^format-check: 2 of 3 files not formatted: run \`make format\`" <<<"$out" &&
    ok "the summary says to run make format" || fail "summary: $out"

"$FMT" fix "$T/bad_indent.c" "$T/bad_brace.c" &&
    cmp -s "$T/good.c" "$T/bad_indent.c" && cmp -s "$T/good.c" "$T/bad_brace.c" &&
    ok "fix restores both" || fail "fix did not restore the files"

# Bad calls: a message, exit 2, nothing rewritten.
cp "$T/good.c" "$T/keep.c"
sed "${line}s/^    /  /" "$T/good.c" > "$T/keep_bad.c"
cp "$T/keep_bad.c" "$T/keep_bad.orig"
out=$(CLANG_FORMAT=/nonexistent/clang-format "$FMT" fix "$T/keep_bad.c" 2>&1)
rc=$?
[ $rc = 2 ] && grep -q "not found: install clang-format" <<<"$out" && cmp -s "$T/keep_bad.c" "$T/keep_bad.orig" &&
    ok "no clang-format: exit 2, says to install it, file untouched" || fail "no clang-format: exit $rc: $out"
out=$(CLANG_FORMAT=/nonexistent/clang-format "$FMT" lint "$T/keep_bad.c" 2>&1)
rc=$?
[ $rc = 0 ] && [ "$out" = "format-check: skip: clang-format not installed" ] &&
    ok "lint without clang-format: a skip line, not ok" || fail "lint without clang-format: exit $rc: $out"
out=$("$FMT" check 2>&1)
rc=$?
[ $rc = 2 ] && grep -q "no files given" <<<"$out" && ok "no files: exit 2" || fail "no files: exit $rc: $out"
out=$("$FMT" check "$T/keep.c" "$T/absent.c" 2>&1)
rc=$?
[ $rc = 2 ] && grep -q "absent.c: no such file" <<<"$out" && ok "a missing file: exit 2, named" ||
    fail "missing file: exit $rc: $out"
out=$("$FMT" fix "$T/keep_bad.c" "$T/absent.c" 2>&1)
rc=$?
[ $rc = 2 ] && cmp -s "$T/keep_bad.c" "$T/keep_bad.orig" && ok "fix with a missing file rewrites nothing" ||
    fail "fix with a missing file: exit $rc, or a file rewritten: $out"
tl_finish
