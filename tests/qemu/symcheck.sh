#!/bin/bash
# Portability check of cross-compiled objects (make cross):
#   symcheck.sh NM SIZE LIBGCC OBJ
# OBJ is a partial (-r) link of the library. Fails, naming the symbol and the
# reason, if OBJ references heap functions, floating-point helpers, or any
# external symbol other than memcpy/memset/memmove and libgcc's integer
# helpers; or if it has writable static data (.data/.bss: global mutable
# state). Exit 0 = clean, 1 = rejected, 2 = usage or tool error.
# SYMCHECK_WAIVE="sym ..." lists libc symbols tolerated with a loud warning
# (a known violation awaiting its fix); heap and float are never waivable.
set -u -o pipefail
if [ $# -ne 4 ]; then
    echo "usage: symcheck.sh NM SIZE LIBGCC OBJ" >&2
    exit 2
fi
nm=$1 size=$2 libgcc=$3 obj=$4

undef=$("$nm" -u "$obj" | awk '{print $NF}' | sort -u) || exit 2
# libgcc's global definitions: readelf next to NM (arm-none-eabi-readelf)
# reads the archive in a tenth of a second; nm loads the LTO plugin for each
# of its members (seconds, and this runs 3 times in make cross and 12 in
# cross-selftest). The same names either way (GLOBAL or WEAK, defined).
readelf=${nm%nm}readelf
if [ "$readelf" != "$nm" ] && command -v "$readelf" >/dev/null; then
    libgcc_defs=$("$readelf" -sW "$libgcc" 2>/dev/null |
                  awk '$5 ~ /^(GLOBAL|WEAK)$/ && $7 != "UND" && NF >= 8 {print $8}' | sort -u) || exit 2
else
    libgcc_defs=$("$nm" --defined-only -g "$libgcc" 2>/dev/null | awk 'NF == 3 {print $3}' | sort -u) || exit 2
fi
[ -n "$libgcc_defs" ] || { echo "symcheck: cannot read $libgcc" >&2; exit 2; }

heap_re='^(_?malloc|_?free|_?calloc|_?realloc|reallocarray|aligned_alloc|posix_memalign|memalign|valloc|pvalloc|_malloc_r|_free_r|_calloc_r|_realloc_r|_?sbrk|brk)$'
# EABI float helpers (__aeabi_fadd, __aeabi_d2iz, __aeabi_i2f, __aeabi_l2d,
# __aeabi_h2f) and GCC soft-float names (__addsf3, __floatsidf, __fixdfsi,
# __extendsfdf2, __truncdfsf2, __powidf2, __unordsf2 ...).
float_re='^__aeabi_([fd][a-z0-9]*|[a-z0-9]+2[fdh]|h2f|f2h|d2h)$|^__[a-z]*(sf|df|tf|xf|hf|bf)[0-9]*$|^__(float|fix|extend|trunc)[a-z0-9]*$|^__gnu_(f2h|h2f|d2h)'
libc_ok_re='^(memcpy|memset|memmove)$'

bad=0
for s in $undef; do
    if [[ $s =~ $heap_re ]]; then
        echo "symcheck: $obj: references $s (heap allocation is not allowed)" >&2; bad=1
    elif [[ $s =~ $float_re ]]; then
        echo "symcheck: $obj: references $s (floating-point helper: no float/double allowed)" >&2; bad=1
    elif [[ $s =~ $libc_ok_re ]]; then
        :
    elif grep -qxF -- "$s" <<<"$libgcc_defs"; then
        : # libgcc integer helper (__aeabi_lmul, __aeabi_uldivmod, __aeabi_idiv, ...)
    elif [[ " ${SYMCHECK_WAIVE:-} " == *" $s "* ]]; then
        echo "symcheck: WARNING: $obj: references $s (libc; WAIVED by SYMCHECK_WAIVE until fixed)" >&2
    else
        echo "symcheck: $obj: references $s (only memcpy/memset/memmove and libgcc integer helpers may be external)" >&2; bad=1
    fi
done

# Writable static data: sum the .data*/.bss* sections (COMMON too).
rw=$("$size" -A "$obj" | awk '$1 ~ /^\.(data|bss|sdata|sbss|tdata|tbss)/ {s += $2} END {print s + 0}') || exit 2
common=$("$nm" "$obj" | awk '$2 == "C" || $2 == "c"' | wc -l)
if [ "$rw" -ne 0 ] || [ "$common" -ne 0 ]; then
    echo "symcheck: $obj: $rw bytes of .data/.bss and $common common symbols (no global mutable state allowed):" >&2
    "$nm" -S "$obj" | awk '$3 ~ /^[bBdDcC]$/ {print "  " $0}' >&2
    bad=1
fi
if [ $bad -eq 0 ]; then
    n=$(printf '%s\n' $undef | grep -c .)
    echo "symcheck: $obj: clean ($n external symbols, all allowed)"
fi
exit $bad
