#!/bin/bash
# The Zephyr module without Zephyr: run zephyr/CMakeLists.txt with stub
# zephyr_* commands (zephyr_stub.cmake, CONFIG_* = the values of
# tests/core/config/it2n_test_config.h), then build exactly the sources,
# include directories and definitions it asked for, with the generated
# IT2N_CONFIG header, together with tests/core/test_config.c, which checks
# that every option took effect. Zephyr's <zephyr/sys/__assert.h> is a stub.
# usage: zephyr_stub.sh CC CFLAGS...   (from the repository root)
set -euo pipefail
work=$(mktemp -d "${TMPDIR:-/tmp}/it2n-zephyr.XXXXXX")
trap 'rm -rf "$work"' EXIT
cmake -DOUT="$work" -P tests/cmake_consumer/zephyr_stub.cmake
mkdir -p "$work/stub/zephyr/sys"
printf '%s\n' '/* stub of Zephyr'\''s assert for the it2n module check */' \
  '#define __ASSERT_NO_MSG(c) ((c) ? (void)0 : __builtin_trap())' >"$work/stub/zephyr/sys/__assert.h"
mapfile -t srcs <"$work/sources.txt"
mapfile -t incs <"$work/includes.txt"
mapfile -t defs <"$work/defines.txt"
"$@" "${incs[@]/#/-I}" "${defs[@]/#/-D}" -I"$work/stub" \
  tests/core/test_config.c "${srcs[@]}" -o "$work/test_config"
echo "zephyr stub: zephyr/CMakeLists.txt asked for ${#srcs[@]} sources, ${#incs[@]} include dirs, ${defs[*]}"
"$work/test_config"
