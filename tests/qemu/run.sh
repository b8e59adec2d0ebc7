#!/bin/bash
# Run a Cortex-M test image on a qemu MPS2 board with semihosting:
#   run.sh IMAGE.elf [MACHINE (mps2-an385)] [TIMEOUT_SECONDS (60)]
# Passes only if qemu exits 0 (the image's semihosting exit status), within
# the timeout, and printed at least one PASS line and no FAIL line.
set -u -o pipefail
elf=$1 machine=${2:-mps2-an385} limit=${3:-60}
log=$(mktemp)
trap 'rm -f "$log"' EXIT
timeout --kill-after=5 "$limit" qemu-system-arm -M "$machine" -nographic \
    -monitor none -serial none \
    -semihosting-config enable=on,target=native -kernel "$elf" </dev/null >"$log" 2>&1
rc=$?
cat "$log"
if [ $rc -eq 124 ] || [ $rc -eq 137 ]; then
    echo "qemu: $elf: timed out after ${limit}s" >&2; exit 1
fi
if [ $rc -ne 0 ]; then
    echo "qemu: $elf: exit status $rc" >&2; exit 1
fi
if grep -q '^FAIL' "$log" || ! grep -q '^PASS' "$log"; then
    echo "qemu: $elf: missing PASS or FAIL reported" >&2; exit 1
fi
echo "qemu: $elf: passed on $machine"
