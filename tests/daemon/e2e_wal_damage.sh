#!/bin/bash
# Damage inside the WAL is never served as complete (issue 20 item 3), with
# the real it2nd: a WAL of 40 acknowledged records (one Modbus upload write
# each), then for several K one byte of record K changed (length, CRC, seq,
# type or payload) or record K removed: the start is refused (exit 1, the
# damage and the records behind it named, nothing served), the WAL left byte
# for byte, a second start refused too. The operator's act (it2nd
# --accept-wal-loss) cuts at the damage, keeps the rest in wal.cut-*, and
# the next start serves exactly the state after K-1 records. A torn tail
# (the last record cut short, damaged, or zeros after it) is still
# recovered silently. Env: IT2ND, IT2ND_SAN, PLC (paths).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
. "$ROOT/tests/lib/testlib.sh"
tl_init wal-damage it2nd-waldmg
PID=
tl_on_exit() {
    [ -n "$PID" ] && kill -9 "$PID" 2>/dev/null
}

PORT=$(free_port)
STATE=$T/state
LOG=$T/daemon.log
CONF=$T/it2nd.conf
printf '[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\n[modbus]\ntcp_listen = 127.0.0.1:%s\n' "$STATE" "$PORT" > "$CONF"
printf '[model:1]\nunit_id = 1\npreload = paper\n[model:2]\nunit_id = 2\nn = 3\nm = 3\n' >> "$CONF"

plc() { "$PLC" --tcp 127.0.0.1:$PORT "$@"; }
gen() { plc --unit 1 read 7 2 | awk '{print $1 * 65536 + $2}'; }
start() { # [binary]: start, wait until it serves
    "${1:-$IT2ND}" -c "$CONF" -f -v >> "$LOG" 2>&1 &
    PID=$!
    tl_wait_served "$PID" && return 0
    fail "daemon did not start: $(tail -3 "$LOG")"; exit 1
}
stop() { tl_stop "$PID" "${1:-TERM}"; PID=; }
start_refused() { # pattern: exit 1 within 10 s, pattern in its log, port never served
    local before rc; before=$(wc -l < "$LOG")
    timeout 10 "$IT2ND" -c "$CONF" -f >> "$LOG" 2>&1; rc=$?
    [ $rc = 1 ] && tail -n +"$((before + 1))" "$LOG" | grep -qE "$1"
}
tval() { echo $((3000 + 10 * $1)); }   # T of write k (x 10000)
UP="0 0 3 65535 63836 0 1700 0 0"      # upload: i j fp D, x -17.00, y 17.00, z 0

# ---- 40 acknowledged records ------------------------------------------------
start
g0=$(gen)
for k in $(seq 40); do
    [ "$(plc write 40 $UP "$(tval "$k")" 7000 2000)" = ok ] || fail "write $k not acknowledged"
done
[ "$(gen)" = $((g0 + 40)) ] || fail "generation after 40 writes: $(gen), want $((g0 + 40))"
stop KILL                                  # no snapshot: everything is in the WAL
cp -a "$STATE" "$T/clean"
# Record offsets and sizes: "k offset size seq" per line.
python3 - "$STATE/wal" > "$T/recs" <<'EOF'
import struct, sys
b = open(sys.argv[1], 'rb').read()
o, k = 16, 0
while o + 8 <= len(b):
    ln = struct.unpack_from('<I', b, o)[0]
    k += 1
    print(k, o, 8 + ln, struct.unpack_from('<Q', b, o + 8)[0])
    o += 8 + ln
EOF
[ "$(wc -l < "$T/recs")" = 40 ] && [ "$(awk 'END {print $4}' "$T/recs")" = 40 ] \
    || fail "the WAL does not hold 40 records: $(wc -l < "$T/recs")"
rec() { awk -v k="$1" '$1 == k {print $'"$2"'}' "$T/recs"; }  # rec K field (2 offset, 3 size)
fresh() { rm -rf "$STATE"; cp -a "$T/clean" "$STATE"; }
flip() { # file offset: invert one byte
    python3 -c "
import sys; p, o = sys.argv[1], int(sys.argv[2]); b = bytearray(open(p, 'rb').read()); b[o] ^= 0x5A; open(p, 'wb').write(b)" "$1" "$2"
}
served_after() { # N: the daemon serves exactly the state after the first N records
    local t g; t=$(plc read 1024 1); g=$(gen)
    [ "$t" = "$(tval "$1")" ] && [ "$g" = $((g0 + $1)) ]
}

# ---- damage inside the log: refused, kept, refused again ---------------------
# K and the byte changed in it (offset inside the record): length, CRC, seq,
# type, payload.
for case in "2 0" "7 5" "13 9" "20 16" "26 30" "33 1" "39 60"; do
    set -- $case
    K=$1 at=$2
    fresh
    flip "$STATE/wal" $(($(rec "$K" 2) + at))
    sum=$(sha256sum < "$STATE/wal")
    if start_refused "wal: .*/wal is damaged inside the log: .* at offset $(rec "$K" 2) after record $((K - 1)), but valid records follow it \($((40 - K)) record\(s\), seq $((K + 1))\.\.40"; then
        if [ "$(sha256sum < "$STATE/wal")" = "$sum" ] && ! ls "$STATE" | grep -q 'cut-\|damaged-' \
            && start_refused "damaged inside the log" && [ "$(sha256sum < "$STATE/wal")" = "$sum" ]; then
            ok "record $K/40, byte $at changed: start refused (nothing served), WAL kept byte for byte, second start refused too"
        else fail "record $K byte $at: WAL changed or second start not refused: $(ls "$STATE")"; fi
    else fail "record $K byte $at: start not refused: $(tail -3 "$LOG")"; fi
    plc read 0 1 >/dev/null 2>&1 && fail "record $K: something serves on port $PORT"
done
# A record removed (the sequence has a hole): refused too.
fresh
python3 -c "
import sys; p, o, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]); b = open(p, 'rb').read(); open(p, 'wb').write(b[:o] + b[o + n:])" \
    "$STATE/wal" "$(rec 17 2)" "$(rec 17 3)"
start_refused "damaged inside the log: sequence break \(records missing\) at offset $(rec 17 2) after record 16, but valid records follow it \(23 record\(s\), seq 18\.\.40" \
    && ok "record 17/40 removed: start refused (sequence break)" || fail "record 17 removed: $(tail -3 "$LOG")"

# ---- the operator's act: --accept-wal-loss ----------------------------------
K=20
fresh
flip "$STATE/wal" $(($(rec $K 2) + 30))
cp "$STATE/wal" "$T/wal.damaged"
start_refused "damaged inside the log" || fail "K=$K not refused before the operator's act"
before=$(wc -l < "$LOG")
timeout 20 "$IT2ND_SAN" -c "$CONF" --accept-wal-loss >> "$LOG" 2>&1; rc=$?
cut=$(ls "$STATE" | grep '^wal\.cut-' | head -1)
if [ $rc = 0 ] && tail -n +"$((before + 1))" "$LOG" | grep -qE "accept-wal-loss: checksum mismatch at offset $(rec $K 2) after record $((K - 1)); the operator accepts the loss .*\(20 valid record\(s\) behind the damage, seq 21\.\.40" \
    && [ "$(stat -c %s "$STATE/wal")" = "$(rec $K 2)" ] && [ -n "$cut" ] \
    && cmp -s "$STATE/$cut" <(tail -c +"$(($(rec $K 2) + 1))" "$T/wal.damaged"); then
    ok "--accept-wal-loss (sanitizer build): exit 0, WAL cut at record $K, the rest kept byte for byte in $cut, the loss logged"
else fail "--accept-wal-loss: rc $rc, $(ls -l "$STATE"), $(tail -3 "$LOG")"; fi
start
served_after $((K - 1)) && ok "after the act: the state after record $((K - 1)) served (T $(plc read 1024 1), generation +$((K - 1)))" \
    || fail "after the act: T $(plc read 1024 1) gen $(gen), want $(tval $((K - 1))) $((g0 + K - 1))"
[ "$(plc write 40 $UP 7777 7000 2000)" = ok ] || fail "write after the act"
stop KILL
start
[ "$(plc read 1024 1)" = 7777 ] && [ "$(gen)" = $((g0 + K)) ] \
    && ok "a write after the act survives kill -9 (the WAL continues at seq $K)" || fail "after the act + kill -9: T $(plc read 1024 1)"
stop TERM

# ---- torn tails: still recovered silently ------------------------------------
torn_case() { # name, how (a python expression on b, the WAL bytes), records expected
    fresh
    python3 -c "
import sys; p = sys.argv[1]; b = open(p, 'rb').read(); b = $2; open(p, 'wb').write(b)" "$STATE/wal"
    local before; before=$(wc -l < "$LOG")
    start
    if served_after "$3" && tail -n +"$((before + 1))" "$LOG" | grep -q "a torn last commit: nothing valid follows it"; then
        ok "torn tail ($1): started, the state after $3 records served"
    else fail "torn tail ($1): T $(plc read 1024 1) gen $(gen), want $(tval "$3") $((g0 + $3))"; fi
    stop KILL
}
L40=$(rec 40 2)
torn_case "last record cut short by 20 bytes" "b[:-20]" 39
torn_case "last record cut after 5 bytes" "b[:$L40 + 5]" 39
torn_case "a byte of the last record changed" "b[:$L40 + 30] + bytes([b[$L40 + 30] ^ 0x5A]) + b[$L40 + 31:]" 39
torn_case "4096 zero bytes after the last record" "b + bytes(4096)" 40
torn_case "last record zeroed, 4096 zeros after" "b[:$L40] + bytes(4096 + len(b) - $L40)" 39
ls "$STATE" | grep -q '^wal\.cut-' && ok "torn tails are kept in wal.cut-* as before" || fail "no wal.cut-* for a torn tail"

tl_finish "$LOG" 30
