#!/bin/bash
# make cmake-consumer: the top-level CMakeLists.txt installs it2n into
# temporary prefixes, and an out-of-tree project (tests/cmake_consumer/)
# uses it through find_package(it2n) and through pkg-config:
#   host:       libraries with the default options; the consumer prints
#               footprint D of the paper's example at (U, W), which must equal
#               `it2n eval --decimals 9` on the D rows of examples/paper_4x4.csv;
#   Cortex-M0+: libraries built with cmake/arm-none-eabi.cmake and
#               -DIT2N_CONFIG=tests/cmake_consumer/it2n_m0p_config.h; the
#               consumer is a freestanding image (-nostdlib, own vector table)
#               that must link with no undefined symbol and no heap or
#               floating-point symbol (arm-none-eabi-nm); the same image
#               with pkg-config and from source with Makefile.firmware.
# Also: the libraries hold exactly firmware_core/*.c and protocol/*.c, a
# host package is refused by a cross build, a hard-float build refuses a
# soft-float package at configure time, and the symbol check rejects an
# image that uses double. ABI guards: abi_user.c, calling every entry point
# whose structs a build option sizes, links and runs with the package's
# options (find_package, add_subdirectory, pkg-config) and fails to link,
# naming each, with others. As a subproject it2n installs nothing unless
# IT2N_INSTALL=ON.
# usage: run.sh IT2N_CLI   (from the repository root)
set -euo pipefail
cli=$(realpath "$1")
root=$PWD
src=$root/tests/cmake_consumer
tc=$root/cmake/arm-none-eabi.cmake
U=0.25 W=0.75
. "$(dirname "$0")/../lib/testlib.sh"
TL_FAIL_FAST=1
tl_init cmake-consumer it2n-cmake
work=$T
log=$work/log
# Run quietly; show the output only when the step fails.
quiet() { "$@" >"$log" 2>&1 || { cat "$log" >&2; fail "$*"; }; }

# ---- the libraries, installed into temporary prefixes ------------------------
quiet cmake -S "$root" -B "$work/lib-host" -DCMAKE_INSTALL_PREFIX="$work/host" -DIT2N_WERROR=ON
quiet cmake --build "$work/lib-host" -j2
quiet cmake --install "$work/lib-host"
say "host libraries built with CMake and installed into a temporary prefix"
quiet cmake -S "$root" -B "$work/lib-m0p" --toolchain "$tc" -DIT2N_WERROR=ON \
  -DIT2N_CONFIG="$src/it2n_m0p_config.h" -DCMAKE_INSTALL_PREFIX="$work/m0p"
quiet cmake --build "$work/lib-m0p" -j2
quiet cmake --install "$work/lib-m0p"
say "Cortex-M0+ libraries (IT2N_CONFIG=it2n_m0p_config.h) installed into a temporary prefix"

for f in lib/libit2n.a lib/libit2n_proto.a lib/libit2n_regmap.a include/it2n/it2n.h include/it2n/it2n_proto.h \
         include/it2n/it2n_regmap.h lib/cmake/it2n/it2nConfig.cmake lib/cmake/it2n/it2nConfigVersion.cmake \
         lib/cmake/it2n/it2nTargets.cmake lib/pkgconfig/it2n.pc lib/pkgconfig/it2n-protocol.pc \
         lib/pkgconfig/it2n-regmap.pc; do
  [ -s "$work/host/$f" ] || fail "host prefix lacks $f"
  [ -s "$work/m0p/$f" ] || fail "M0+ prefix lacks $f"
done
[ -s "$work/m0p/include/it2n/it2n_m0p_config.h" ] || fail "the IT2N_CONFIG header was not installed"
for f in it2n_internal.h it2n_fixed.h it2n_xf.h it2n_vectors.inc; do
  [ ! -e "$work/host/include/it2n/$f" ] || fail "internal header $f installed"
done

# Same sources as the Makefile: one object per firmware_core/*.c, protocol/*.c.
objs() { ar t "$1" | sed -E 's/\.(o|obj)$//' | sort; }
srcs() { for f in "$root/$1"/*.c; do basename "$f"; done | sort; }
for a in host m0p; do
  diff <(objs "$work/$a/lib/libit2n.a") <(srcs firmware_core) >/dev/null ||
    fail "$a libit2n.a does not hold exactly firmware_core/*.c"
  diff <(objs "$work/$a/lib/libit2n_proto.a") <(srcs protocol) >/dev/null ||
    fail "$a libit2n_proto.a does not hold exactly protocol/*.c"
  diff <(objs "$work/$a/lib/libit2n_regmap.a") <(srcs regmap) >/dev/null ||
    fail "$a libit2n_regmap.a does not hold exactly regmap/*.c"
done
say "libit2n.a = firmware_core/*.c, libit2n_proto.a = protocol/*.c, libit2n_regmap.a = regmap/*.c (host and M0+)"

# ---- expected value: the CLI on the D rows of the paper's example -------------
{ head -n 1 "$root/examples/paper_4x4.csv"; grep -E '^[0-9]+,[0-9]+,D,' "$root/examples/paper_4x4.csv"; } \
  >"$work/paper_d.csv"
"$cli" eval "$work/paper_d.csv" --at "$U,$W" --decimals 9 | cut -d, -f1-8 >"$work/expected.csv"
[ "$(wc -l <"$work/expected.csv")" = 2 ] || fail "unexpected CLI output"

check_host_output() { # $1 = program, $2 = label
  "$1" "$U" "$W" >"$work/got.csv" || fail "$2 exited with status $?"
  diff -u "$work/expected.csv" "$work/got.csv" || fail "$2 differs from it2n eval"
  say "$2: D at ($U, $W) = $(tail -n 1 "$work/got.csv" | cut -d, -f6-8) (T, I, F), same as it2n eval"
}

# ---- host consumer: find_package(it2n) ----------------------------------------
quiet cmake -S "$src" -B "$work/consumer-host" -DCMAKE_PREFIX_PATH="$work/host" -DCMAKE_BUILD_TYPE=Release
quiet cmake --build "$work/consumer-host"
check_host_output "$work/consumer-host/consumer" "host consumer (find_package)"
got=$("$work/consumer-host/regmap_user") || fail "regmap_user (it2n::regmap) exited with status $?"
[ "$got" = "0000 3fc0 sample_grid 5000" ] || fail "regmap_user (it2n::regmap) printed '$got'"

# ABI guards (it2n.h, it2n_proto.h): abi_user calls every entry point whose
# structs a build option sizes. With the package's options it links and
# runs; given another value of an option it must fail to link, naming each
# entry point with the values it asked for. $1 = log, $2 = label, rest =
# the undefined names expected (every other link error is a failure).
abi_names() { # $1 = core suffix, $2 = protocol suffix, $3 = B-spline suffix ("-" or none: that part matches)
  [ "$1" = - ] || for f in it2n_dataset_init it2n_model_init; do echo "${f}_abi_$1"; done
  [ "$2" = - ] || for f in it2n_msg_pack it2n_msg_unpack it2n_proto_vector it2n_frame_decoder_init \
                           it2n_link_init it2n_inst_open; do echo "${f}_abi_$2"; done
  [ "${3:--}" = - ] || echo "it2n_bspline_data_init_abi_$3"
}
check_abi_refused() { # $1 = linker output, $2 = label, $3 = core suffix, $4 = protocol suffix, $5 = B-spline suffix
  local s
  for s in $(abi_names "$3" "$4" "${5:-}"); do
    grep -q "undefined reference to .$s'" "$1" ||
      { cat "$1" >&2; fail "ABI guard, $2: the link error does not name $s"; }
  done
  [ "$(grep -c 'undefined reference' "$1")" = "$(abi_names "$3" "$4" "${5:-}" | wc -l)" ] ||
    { cat "$1" >&2; fail "ABI guard, $2: other link errors than the guarded names"; }
}
"$work/consumer-host/abi_user" >"$log" 2>&1 || { cat "$log" >&2; fail "abi_user (find_package) failed"; }
say "host abi_user (find_package, package options): $(cat "$log")"
n_abi=0
for defs in "IT2N_MAX_DEGREE=3:degree3_chord1:window4_payload1024_reorder1_degree3" \
            "IT2N_PROTO_WINDOW=16:-:window16_payload1024_reorder1_degree7" \
            "IT2N_CHORD=0:degree7_chord0:-" \
            "IT2N_BSPLINE_MAX_N=63:-:-:bspline63"; do
  IFS=: read -r def core proto bs <<<"$defs"
  quiet cmake -S "$src" -B "$work/consumer-abi" -DCMAKE_PREFIX_PATH="$work/host" \
    -DCMAKE_BUILD_TYPE=Release -DCONSUMER_ABI_DEFINES="$def"
  if cmake --build "$work/consumer-abi" --target abi_user >"$log" 2>&1; then
    fail "ABI guard: abi_user compiled with $def linked against the package (default options)"
  fi
  check_abi_refused "$log" "find_package, $def" "$core" "$proto" "$bs"
  n_abi=$((n_abi + 1))
done
say "host abi_user (find_package) compiled with IT2N_MAX_DEGREE=3, IT2N_PROTO_WINDOW=16," \
  "IT2N_CHORD=0 or IT2N_BSPLINE_MAX_N=63: $n_abi of $n_abi fail to link, naming every guarded entry point"

# ---- host consumer: it2n's source tree with add_subdirectory ------------------
quiet cmake -S "$src" -B "$work/consumer-subdir" -DCONSUMER_IT2N_SOURCE="$root" -DCMAKE_BUILD_TYPE=Release
quiet cmake --build "$work/consumer-subdir" -j2
check_host_output "$work/consumer-subdir/consumer" "host consumer (add_subdirectory)"
"$work/consumer-subdir/abi_user" >"$log" 2>&1 || { cat "$log" >&2; fail "abi_user (add_subdirectory) failed"; }
# As a subproject (added as FetchContent does, not EXCLUDE_FROM_ALL) it2n
# installs nothing unless asked with IT2N_INSTALL=ON.
quiet cmake -S "$src" -B "$work/consumer-subdir" -DCONSUMER_IT2N_EXCLUDE_FROM_ALL=OFF
quiet cmake --build "$work/consumer-subdir" -j2
quiet cmake --install "$work/consumer-subdir" --prefix "$work/sub-inst"
got=$(cd "$work/sub-inst" && find . -type f | sort | tr '\n' ' ')
[ "$got" = "./bin/consumer " ] || fail "as a subproject (IT2N_INSTALL default) it2n installed files: $got"
quiet cmake -S "$src" -B "$work/consumer-subdir" -DIT2N_INSTALL=ON
quiet cmake --install "$work/consumer-subdir" --prefix "$work/sub-inst-on"
for f in bin/consumer lib/libit2n.a lib/libit2n_proto.a include/it2n/it2n.h lib/cmake/it2n/it2nConfig.cmake \
         lib/pkgconfig/it2n.pc; do
  [ -s "$work/sub-inst-on/$f" ] || fail "subproject with IT2N_INSTALL=ON: $f not installed"
done
say "as a subproject it2n installs nothing by default, its libraries, headers and package with IT2N_INSTALL=ON"

# ---- host consumer: pkg-config ---------------------------------------------------
export PKG_CONFIG_PATH="$work/host/lib/pkgconfig"
quiet gcc -std=c99 -O2 -Wall -Wextra -Wpedantic -Wconversion -Werror \
  $(pkg-config --cflags it2n-protocol) "$src/host_main.c" "$src/paper_model.c" \
  $(pkg-config --libs it2n-protocol) -o "$work/consumer-pc"
check_host_output "$work/consumer-pc" "host consumer (pkg-config it2n-protocol)"
quiet gcc -std=c99 -Wall -Wextra -Werror $(pkg-config --cflags it2n-protocol) "$src/abi_user.c" \
  $(pkg-config --libs it2n-protocol) -o "$work/abi-pc"
"$work/abi-pc" >"$log" 2>&1 || { cat "$log" >&2; fail "abi_user (pkg-config) failed"; }
if gcc -std=c99 $(pkg-config --cflags it2n-protocol) -DIT2N_MAX_DEGREE=5 -DIT2N_PROTO_MAX_PAYLOAD=2048 \
     "$src/abi_user.c" $(pkg-config --libs it2n-protocol) -o "$work/abi-pc-bad" >"$log" 2>&1; then
  fail "ABI guard: abi_user with IT2N_MAX_DEGREE=5 IT2N_PROTO_MAX_PAYLOAD=2048 linked (pkg-config)"
fi
check_abi_refused "$log" "pkg-config, degree 5, payload 2048" degree5_chord1 window4_payload2048_reorder1_degree5
say "host abi_user (pkg-config): links and runs with the .pc flags; with IT2N_MAX_DEGREE=5" \
  "IT2N_PROTO_MAX_PAYLOAD=2048 it fails to link, naming every guarded entry point"

# ---- Cortex-M0+ image ---------------------------------------------------------
# $1 = ELF, $2 = label: fully linked, and no heap or float symbol anywhere.
heap_re='^(_?malloc|_?free|_?calloc|_?realloc|reallocarray|aligned_alloc|posix_memalign|memalign|valloc|pvalloc|_malloc_r|_free_r|_calloc_r|_realloc_r|_?sbrk|brk|_sbrk_r)$'
float_re='^__aeabi_([fd][a-z0-9]*|[a-z0-9]+2[fdh]|h2f|f2h|d2h)$|^__[a-z]*(sf|df|tf|xf|hf|bf)[0-9]*$|^__(float|fix|extend|trunc)[a-z0-9]*$|^__gnu_(f2h|h2f|d2h)'
check_image() {
  local undef bad
  undef=$(arm-none-eabi-nm -u "$1")
  [ -z "$undef" ] || { echo "$undef" >&2; echo "$2: undefined symbols"; return 1; }
  bad=$(arm-none-eabi-nm "$1" | awk '{print $NF}' | grep -E "$heap_re|$float_re" || true)
  [ -z "$bad" ] || { echo "$2: heap/float symbols linked in:" "${bad//$'\n'/ }"; return 1; }
  for s in consumer_reset it2n_model_solve it2n_eval it2n_crc32c; do
    arm-none-eabi-nm "$1" | grep -q " T $s\$" || { echo "$2: $s not linked"; return 1; }
  done
}
quiet cmake -S "$src" -B "$work/consumer-m0p" --toolchain "$tc" -DCMAKE_PREFIX_PATH="$work/m0p" \
  -DCMAKE_BUILD_TYPE=MinSizeRel
quiet cmake --build "$work/consumer-m0p"
elf=$work/consumer-m0p/consumer_m0p.elf
grep -q -- '-mcpu=cortex-m0plus' "$work/consumer-m0p/CMakeFiles/consumer_m0p.dir/flags.make" ||
  fail "the M0+ consumer was not compiled for cortex-m0plus"
msg=$(check_image "$elf" "M0+ image (find_package)") || fail "$msg"
say "Cortex-M0+ image (find_package): linked freestanding, no heap/float symbols;" \
  "$(arm-none-eabi-size -B "$elf" | awk 'NR==2 {print "text " $1 ", data " $2 ", bss " $3}') bytes"

# The same with pkg-config (IT2N_CONFIG must come with --cflags).
export PKG_CONFIG_PATH="$work/m0p/lib/pkgconfig"
pkg-config --cflags it2n | grep -q -- '-DIT2N_CONFIG=it2n_m0p_config.h' ||
  fail "pkg-config --cflags it2n lacks -DIT2N_CONFIG=it2n_m0p_config.h"
quiet arm-none-eabi-gcc -mcpu=cortex-m0plus -mthumb -std=c99 -Os -ffreestanding -Wall -Wextra \
  -Wpedantic -Wconversion -Werror $(pkg-config --cflags it2n-protocol) \
  "$src/mcu_main.c" "$src/paper_model.c" -nostdlib -Wl,--gc-sections -T "$src/m0p.ld" \
  $(pkg-config --libs it2n-protocol) -lc -lgcc -o "$work/consumer-m0p-pc.elf"
msg=$(check_image "$work/consumer-m0p-pc.elf" "M0+ image (pkg-config)") || fail "$msg"
say "Cortex-M0+ image (pkg-config it2n-protocol): linked freestanding, no heap/float symbols"
# Without the .pc flags (no -DIT2N_CONFIG): degree 7 with chord against a
# library built for degree 3 without: refused at link time.
if arm-none-eabi-gcc -mcpu=cortex-m0plus -mthumb -std=c99 -Os -ffreestanding -DCONSUMER_NO_CONFIG_CHECK \
     -I"$work/m0p/include/it2n" "$src/mcu_main.c" "$src/paper_model.c" -nostdlib -Wl,--gc-sections \
     -T "$src/m0p.ld" $(pkg-config --libs it2n-protocol) -lc -lgcc -o "$work/m0p-noconfig.elf" >"$log" 2>&1; then
  fail "ABI guard: an M0+ image compiled without IT2N_CONFIG linked against the degree-3 library"
fi
grep -q "undefined reference to .it2n_dataset_init_abi_degree7_chord1'" "$log" ||
  { cat "$log" >&2; fail "ABI guard: M0+ image without IT2N_CONFIG: not the expected link error"; }
say "an M0+ image compiled without the .pc flags (degree 7, chord) fails to link:" \
  "undefined it2n_dataset_init_abi_degree7_chord1 (the library has degree 3, no chord)"

# From source in a plain Makefile (docs/firmware.md quotes Makefile.firmware).
quiet make -s -j2 -f "$src/Makefile.firmware" IT2N="$root" APP="$src" OUT="$work/plain"
msg=$(check_image "$work/plain/firmware.elf" "M0+ image (plain Makefile)") || fail "$msg"
say "Cortex-M0+ image (plain Makefile from source, Makefile.firmware): linked freestanding, no heap/float symbols"

# The check must catch a double (soft-float helpers) in an otherwise clean image.
printf '%s\n' '#include "paper_model.h"' 'volatile double consumer_bad_d;' \
  'int consumer_bad(void);' 'int consumer_bad(void) { return (int)(consumer_bad_d * 2.5); }' \
  >"$work/bad.c"
sed 's/consumer_status = rc;/consumer_status = rc + consumer_bad();/' "$src/mcu_main.c" >"$work/bad_main.c"
sed -i '/^void consumer_reset(void);/a int consumer_bad(void);' "$work/bad_main.c"
quiet arm-none-eabi-gcc -mcpu=cortex-m0plus -mthumb -std=c99 -Os -ffreestanding -I"$src" \
  $(pkg-config --cflags it2n-protocol) "$work/bad_main.c" "$work/bad.c" "$src/paper_model.c" \
  -nostdlib -Wl,--gc-sections -T "$src/m0p.ld" \
  $(pkg-config --libs it2n-protocol) -lc -lgcc -o "$work/bad.elf"
if msg=$(check_image "$work/bad.elf" "image with double"); then
  fail "the symbol check accepted an image that uses double"
fi
echo "$msg" | grep -q '__aeabi_d' || fail "the symbol check rejected the double image for the wrong reason: $msg"
say "symbol check rejects an image using double (${msg#*: })"

# A host build must refuse the Cortex-M0+ package (and name why).
if cmake -S "$src" -B "$work/consumer-wrong" -DCMAKE_PREFIX_PATH="$work/m0p" >"$log" 2>&1; then
  fail "a host build accepted the Cortex-M0+ package"
fi
grep -q 'Generic/arm' "$log" || { cat "$log" >&2; fail "the refusal does not name the package's target"; }
say "a host build refuses the Cortex-M0+ package (built for Generic/arm)"

# A Cortex-M4 build finds the Cortex-M0+ package but is warned.
quiet cmake -S "$src" -B "$work/consumer-m4" --toolchain "$tc" -DIT2N_ARM_CPU=cortex-m4 \
  -DCMAKE_PREFIX_PATH="$work/m0p"
tr -s '\n ' '  ' <"$log" | grep -q "built with '-mcpu=cortex-m0plus', this build has '-mcpu=cortex-m4'" || { cat "$log" >&2; fail "no warning for a package of another CPU"; }
say "a Cortex-M4 build is warned that the package is for -mcpu=cortex-m0plus"

# A hard-float build is refused at configure time (with a message naming
# both calling conventions), not with a linker error per object.
if cmake -S "$src" -B "$work/consumer-m4hf" --toolchain "$tc" -DIT2N_ARM_CPU=cortex-m4 \
     -DIT2N_ARM_FLAGS="-mfloat-abi=hard -mfpu=fpv4-sp-d16" -DCMAKE_PREFIX_PATH="$work/m0p" >"$log" 2>&1; then
  fail "a -mfloat-abi=hard build accepted the soft-float Cortex-M0+ package"
fi
tr -s '\n ' '  ' <"$log" | grep -q "built for the soft-float calling convention .* this build uses the hard-float one" ||
  { cat "$log" >&2; fail "the float-ABI refusal does not name both calling conventions"; }
# softfp passes floats as soft does: accepted (warned for the CPU only).
quiet cmake -S "$src" -B "$work/consumer-m4sfp" --toolchain "$tc" -DIT2N_ARM_CPU=cortex-m4 \
  -DIT2N_ARM_FLAGS="-mfloat-abi=softfp -mfpu=fpv4-sp-d16" -DCMAKE_PREFIX_PATH="$work/m0p"
say "a -mfloat-abi=hard build is refused at configure time (package: soft-float calling convention);" \
  "-mfloat-abi=softfp is accepted"
say "ok"
