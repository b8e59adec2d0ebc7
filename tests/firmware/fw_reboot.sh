#!/bin/bash
# Exactly once across reboots on qemu (docs/protocol.md 4.1, issue 17):
# the instrument firmware of examples/firmware/ (its reboot-test image) on
# qemu mps2-an385 with deterministic timing (-icount shift=5: every boot
# alike, as on silicon, so nothing of the protocol differs between boots),
# UART0 on a pty served by one it2nd throughout. The board is reset
# (monitor system_reset) FW_REBOOTS times at random points — during HELLO,
# CONFIGURE, the PUTs, the QUERYs — each boot taking another measurement
# (two alternating data sets, chosen by the host file fw-seed). The last
# boot runs to the end and must see every QUERY_RESULT bit-identical to its
# own evaluation (a stale entry of the other data set, or an acknowledged
# one missing, changes the solve or gets a DUPLICATE refusal), Modbus
# float32 results bit-identical too; the daemon must have taken every
# boot's HELLO as a new session (none taken for a retransmission) and never
# declared the link down (no timeout).
# Env: IT2ND, FW_ELF (the reboot image), FW_REBOOTS (default 30);
# FW_EXPECT_FAIL=1 for the image with the v1.1 handshake (make
# fw-reboot-legacy): then the test passes only if the checks fail.
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
. "$ROOT/tests/lib/testlib.sh"
tl_init fw-reboot it2n-fwr
TL_KEEP=${FW_KEEP:-}
QPID='' DPID=''
N=${FW_REBOOTS:-30}
EXPECT_FAIL=${FW_EXPECT_FAIL:-0} # 1: an image with the old handshake, which must fail
ELF=$(realpath "$FW_ELF")

stop_pids() {
    local p
    for p in $QPID $DPID; do
        kill "$p" 2>/dev/null && wait "$p" 2>/dev/null
    done
    QPID='' DPID=''
}
tl_on_exit() { stop_pids; }
# The verdict: checks failed or not, against what was expected.
finish() {
    stop_pids
    if [ "$EXPECT_FAIL" = 1 ]; then
        if [ "$FAILS" != 0 ]; then
            echo "fw-reboot: the v1.1 handshake failed the test ($FAILS check(s)), as expected"
            FAILS=0; exit 0
        fi
        echo "fw-reboot: FAIL: the v1.1 handshake passed: the test cannot tell" >&2; FAILS=1; exit 1
    fi
    tl_finish
}
count() { grep -c "$1" "$2" 2>/dev/null || true; }

mkdir -p "$T/state"
port=$(free_port)
echo 1111 > "$T/fw-seed"
(cd "$T" && exec qemu-system-arm -M mps2-an385 -display none -S -icount shift=5 \
    -monitor "unix:$T/mon.sock,server=on,wait=off" -serial pty \
    -semihosting-config enable=on,target=native -kernel "$ELF" \
    </dev/null >>"$T/qemu.log" 2>&1) &
QPID=$!
pty=''
for _ in $(seq 100); do
    pty=$(sed -n 's/.*char device redirected to \(\/dev\/pts\/[0-9]*\).*/\1/p' "$T/qemu.log")
    [ -n "$pty" ] && [ -S "$T/mon.sock" ] && break
    sleep 0.05
done
[ -n "$pty" ] || { fail "qemu gave no pty"; cat "$T/qemu.log" >&2; exit 1; }
printf '[daemon]\nstate_dir = %s\nlink_backoff_max = 1\n[modbus]\ntcp_listen = 127.0.0.1:%s\n' \
    "$T/state" "$port" > "$T/it2nd.conf"
printf '[model:1]\nunit_id = 1\nn = 3\nm = 3\n[link:fw]\ntype = serial\ndevice = %s\nbaud = 115200\n' \
    "$pty" >> "$T/it2nd.conf"
"$IT2ND" -c "$T/it2nd.conf" -f -v >"$T/daemon.log" 2>&1 &
DPID=$!
wait_port "$port" "$DPID"
kill -0 "$DPID" 2>/dev/null || { fail "it2nd did not start"; cat "$T/daemon.log" >&2; exit 1; }
sleep 0.2

t0=$(date +%s%N)
python3 "$ROOT/tests/firmware/fw_reset.py" "$T/mon.sock" "$T/daemon.log" "$T/qemu.log" "$T/fw-seed" "$N" 1111 2222 \
    > "$T/resets.txt" 2>&1 || { fail "resets: $(tail -1 "$T/resets.txt") (a stall)"; finish; }
off=$(sed -n 's/^LAST_OFF //p' "$T/resets.txt")
seed=$(sed -n 's/^SEED_LAST //p' "$T/resets.txt")
phases=$(sed -n '/^boot /p' "$T/resets.txt")
# the last boot runs to the end
for _ in $(seq 900); do
    tail -c +"$((off + 1))" "$T/qemu.log" | grep -q -E '^(PASS firmware|FAIL)' && break
    kill -0 "$QPID" 2>/dev/null || break
    sleep 0.1
done
tail -c +"$((off + 1))" "$T/qemu.log" > "$T/last.log"
ms=$(( ($(date +%s%N) - t0) / 1000000 ))
echo "fw-reboot: $N resets in $ms ms; reset during (the latest exchange of the boot): $phases"
grep -E '^(SEED|UPLOAD|QUERY)' "$T/last.log"
if grep -q '^PASS firmware' "$T/last.log" && ! grep -q '^FAIL' "$T/last.log" &&
   grep -q "^SEED $seed\$" "$T/last.log"; then
    ok "last boot (measurement $seed): upload committed, every QUERY_RESULT bit-identical to its own evaluation"
else
    fail "last boot did not pass"; tail -20 "$T/qemu.log" >&2
fi
if /usr/bin/python3 "$ROOT/tests/firmware/fw_check.py" "$port" "$T/last.log" 1; then
    ok "Modbus float32 results bit-identical to the last boot's evaluations (0 stale entries)"
else
    fail "Modbus results differ from the last boot's data set"
fi
hellos=$(count 'HELLO from .*v1.2, new session' "$T/daemon.log")
[ "$EXPECT_FAIL" = 1 ] && hellos=$(count 'HELLO from' "$T/daemon.log") # v1.1: sessions of its own
downs=$(count 'declared down' "$T/daemon.log")
dups=$(count 'refused: duplicate' "$T/daemon.log")
foreign=$(count 'refused' "$T/daemon.log")
echo "fw-reboot: daemon: $hellos v1.2 sessions handed out for $((N + 1)) boots, $dups DUPLICATE refusals, $downs link-down declarations"
# boots reset before their HELLO left send none
early=$(echo "$phases" | sed -n 's/^boot \([0-9]*\),.*/\1/p')
# (a HELLO retransmitted before its answer came gets one more)
[ "$hellos" -ge "$((N + 1 - early))" ] \
    && ok "every boot's HELLO got a new session ($hellos for $((N + 1)) boots; $early reset before their HELLO)" \
    || fail "$hellos sessions for $((N + 1)) boots ($early reset before HELLO)"
# recovery of each boot: from its HELLO reaching the daemon to its
# CONFIGURE (one HELLO exchange; a stall would be retries of 150 ms)
read -r ngap maxgap <<< "$(sed -n 's/^HELLO_TO_CONFIGURE_MS //p' "$T/resets.txt")"
[ "${ngap:-0}" -gt 0 ] && [ "$maxgap" -le 700 ] \
    && ok "$ngap boots seen from HELLO to CONFIGURE: at most $maxgap ms (bound 2 RTO + 400 ms = 700; a stall is seconds)" \
    || fail "HELLO to CONFIGURE: ${maxgap:-?} ms over ${ngap:-0} boots"
up=$(sed -n 's/^UPLOAD committed ms \([0-9]*\).*/\1/p' "$T/last.log")
[ -n "$up" ] && [ "$up" -le 1000 ] && ok "last boot: HELLO to COMMIT's ACK in $up ms (no stall)" \
    || fail "last boot's upload took ${up:-?} ms"
[ "$downs" = 0 ] && ok "never a timeout (the link was never declared down)" || fail "$downs link-down declarations"
[ "$dups" = 0 ] && ok "no DUPLICATE: no entry of the other measurement was ever taken for this one's" \
    || fail "$dups DUPLICATE refusals: stale entries ($foreign refusals in all)"
finish
