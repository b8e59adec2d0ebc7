#!/bin/sh
# Flash and RAM of the docs/instrument.md example on a Cortex-M0+: the
# example (extracted from the doc), the instrument API and the protocol/
# code it pulls in, linked with --gc-sections against libgcc and
# memcpy/memset only (no core: the instrument needs none of it).
#   inst_size.sh EXAMPLE.c OUTDIR [--json FILE] [--check DOC]
# --json writes bench rows; --check fails if DOC's figure line differs.
set -eu
EX=$1 OUT=$2; shift 2
CC=arm-none-eabi-gcc
CPU="-mcpu=cortex-m0plus -mthumb"
CFLAGS="-ffreestanding -std=c99 -Os -ffunction-sections -fdata-sections -Ifirmware_core -Iprotocol"
mkdir -p "$OUT"
cat > "$OUT/board_stub.c" <<'C'
/* Stand-ins for the board functions the example declares; the entry calls
 * the example so --gc-sections keeps what an instrument links. */
#include "it2n_inst.h"
int board_uart_write(const uint8_t *buf, size_t len);
int board_uart_read(uint8_t *buf, size_t len);
uint32_t board_millis(void);
uint32_t board_boot_count(void);
int upload_and_query(it2n_val *t_centre, it2n_msg_nack *why);
void inst_entry(void);
static volatile uint8_t sink;
int board_uart_write(const uint8_t *buf, size_t len) { while (len--) sink = *buf++; return 0; }
int board_uart_read(uint8_t *buf, size_t len) { (void)buf; (void)len; return 0; }
uint32_t board_millis(void) { return sink; }
uint32_t board_boot_count(void) { return 1; }
void inst_entry(void)
{
    it2n_val t;
    it2n_msg_nack why;
    (void)upload_and_query(&t, &why);
}
C
objs=""
for f in "$EX" "$OUT/board_stub.c" protocol/it2n_inst.c protocol/it2n_link.c protocol/it2n_msg.c \
         protocol/it2n_frame.c protocol/it2n_cobs.c protocol/it2n_crc32.c; do
    o="$OUT/$(basename "$f" .c).o"
    $CC $CPU $CFLAGS -c "$f" -o "$o"
    objs="$objs $o"
done
$CC $CPU -nostdlib -Wl,--gc-sections -Wl,-e,inst_entry -o "$OUT/inst.elf" $objs -lc -lgcc
set -- "$@" ""
eval "$(arm-none-eabi-size -A "$OUT/inst.elf" | awk '
  $1 ~ /^\.(text|rodata)/ {t += $2} $1 == ".data" {d += $2} $1 == ".bss" {b += $2}
  END {printf "FLASH=%d RAM=%d\n", t + d, d + b}')"
CTX=$(printf '#include "it2n_inst.h"\nchar x[sizeof(it2n_inst)];\n' | $CC $CPU $CFLAGS -x c -c - -o "$OUT/ctx.o" && \
      printf '%d' "0x$(arm-none-eabi-nm -S "$OUT/ctx.o" | awk '$4 == "x" {print $2}')")
LINE="Cortex-M0+, -Os: flash $FLASH bytes, static RAM $RAM bytes (the it2n_inst context: $CTX bytes)."
echo "$LINE"
while [ $# -gt 0 ] && [ -n "$1" ]; do
    case $1 in
    --json)
        cat > "$2" <<J
{
  "bench": "instrument_api",
  "what": "docs/instrument.md example + protocol/it2n_inst.c and the protocol/ code it links, arm-none-eabi-gcc -mcpu=cortex-m0plus -Os, --gc-sections",
  "rows": [
    {"name": "instrument API flash (Cortex-M0+, -Os)", "unit": "bytes", "value": $FLASH, "baseline": null, "ratio": null, "target": null, "met": null},
    {"name": "instrument API static RAM (Cortex-M0+)", "unit": "bytes", "value": $RAM, "baseline": null, "ratio": null, "target": null, "met": null},
    {"name": "it2n_inst context (Cortex-M0+)", "unit": "bytes", "value": $CTX, "baseline": null, "ratio": null, "target": null, "met": null}
  ]
}
J
        shift 2 ;;
    --check)
        grep -qxF "$LINE" "$2" || { echo "$2: size figure is stale; it should read:" >&2; echo "$LINE" >&2; exit 1; }
        echo "$2: size figure is current"
        shift 2 ;;
    *) shift ;;
    esac
done
