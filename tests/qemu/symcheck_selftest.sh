#!/bin/bash
# Negative self-test of symcheck.sh (make test): each selftest/bad_*.c must be
# rejected for its stated reason, selftest/good.c must pass, on every target.
#   symcheck_selftest.sh OUTDIR CC NM SIZE "CFLAGS" "CPU FLAGS" ["CPU FLAGS"...]
set -u -o pipefail
out=$1 cc=$2 nm=$3 size=$4 cflags=$5
shift 5
here=$(dirname "$0")
declare -A reason=(
    [good]=""
    [bad_malloc]="heap allocation"
    [bad_float]="floating-point helper"
    [bad_double]="floating-point helper"
    [bad_libc]="only memcpy/memset/memmove"
    [bad_global]="no global mutable state"
)
mkdir -p "$out"
fail=0 n=0
for cpu in "$@"; do
    libgcc=$($cc $cpu -print-libgcc-file-name)
    tag=$(echo "$cpu" | tr -c 'a-z0-9\n' '_')
    for name in "${!reason[@]}"; do
        obj="$out/${name}_$tag.o"
        # shellcheck disable=SC2086
        $cc $cpu $cflags -c "$here/selftest/$name.c" -o "$obj" || { echo "symcheck selftest: cannot compile $name.c" >&2; exit 1; }
        msg=$("$here/symcheck.sh" "$nm" "$size" "$libgcc" "$obj" 2>&1)
        rc=$?
        n=$((n + 1))
        want=${reason[$name]}
        if [ -z "$want" ]; then
            [ $rc -eq 0 ] || { echo "symcheck selftest: $name ($cpu) should pass, got $rc: $msg" >&2; fail=1; }
        elif [ $rc -ne 1 ] || ! grep -qF -- "$want" <<<"$msg"; then
            echo "symcheck selftest: $name ($cpu) should be rejected for '$want', got $rc: $msg" >&2; fail=1
        fi
    done
done
[ $fail -eq 0 ] && echo "symcheck selftest: $n cases behave as expected (1 accepted, 5 rejected per target)"
exit $fail
