#!/bin/bash
# End-to-end tests of the real it2nd binary on localhost TCP: a random free
# port, a temporary state directory, the simulated PLC (libmodbus), mbpoll
# and pymodbus as third-party clients, crash/restart, corrupted files,
# SIGHUP reload, and the sd_notify protocol on a test socket.
# Env: IT2ND, IT2ND_SAN, PLC (paths to the binaries).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PAPER=$ROOT/examples/paper_4x4.csv
. "$ROOT/tests/lib/testlib.sh"
tl_init e2e it2nd-e2e
PID=

tl_on_exit() {
    [ -n "$PID" ] && kill -9 "$PID" 2>/dev/null
    [ -n "${NPID:-}" ] && kill "$NPID" 2>/dev/null
    [ -n "${BPID:-}" ] && kill "$BPID" 2>/dev/null
    [ -n "${BPID485:-}" ] && kill "$BPID485" 2>/dev/null
    [ -n "${EPID:-}" ] && kill -CONT "$EPID" 2>/dev/null && kill "$EPID" 2>/dev/null
}

PORT=$(free_port)
STATE=$T/state
# Null-modem pty pair for Modbus RTU: the daemon on side A, clients on B.
"$PTY" > "$T/pty" &
BPID=$!
for _ in $(seq 50); do [ -s "$T/pty" ] && break; sleep 0.02; done
read -r RTU_A RTU_B < "$T/pty"

write_conf() { # extra lines on stdin
    {
        printf '[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\nlink_backoff_max = 1\n' "$STATE"
        printf '[modbus]\ntcp_listen = 127.0.0.1:%s\nbyte_timeout = 400\n' "$PORT"
        python3 -c 'import socket; s=socket.socket(socket.AF_INET6); s.bind(("::1", 0))' 2>/dev/null \
            && printf 'tcp_listen = [::1]:%s\n' "$PORT"
        printf '[rtu:bus]\ndevice = %s\nbaud = 19200\n' "$RTU_A"
        cat
    } > "$T/it2nd.conf"
}

models_conf() {
    printf '[model:1]\nunit_id = 1\npreload = paper\n'
    printf '[model:2]\nunit_id = 2\nn = 3\nm = 3\n'
    printf '[model:3]\nunit_id = 3\nn = 3\nm = 2\ntype1 = yes\n'
    printf '[model:4]\nunit_id = 4\nn = 2\nm = 2\nz = yes\n'
    printf '[model:5]\nunit_id = 5\nn = 3\nm = 3\n'
    printf '[model:6]\nunit_id = 6\nn = 2\nm = 2\n'
    printf '[link:inst]\ntype = serial\ndevice = %s\nbaud = 115200\n' "$T/inst0"
    printf '[link:ev]\ntype = serial\ndevice = %s\nbaud = 115200\n' "$T/ev0"
}
instr() { timeout 60 "$INSTR" --link "$T/inst0" "$@"; }

start() { # binary
    local bin=${1:-$IT2ND}
    "$bin" -c "${CONF:-$T/it2nd.conf}" -f -v >> "$T/daemon.log" 2>&1 &
    PID=$!
    tl_wait_served "$PID" && return 0
    fail "daemon did not start"; cat "$T/daemon.log" >&2; exit 1
}

stop() { # signal
    local rc
    tl_stop "$PID" "${1:-TERM}"
    rc=$?
    PID=
    return $rc
}

plc() { "$PLC" --tcp 127.0.0.1:$PORT "$@"; }

# ---- configuration errors --------------------------------------------------
printf '[modbus]\ncoord_scale = 0\n' > "$T/bad.conf"
msg=$("$IT2ND" -c "$T/bad.conf" --check-config 2>&1); rc=$?
if [ $rc -ne 0 ] && echo "$msg" | grep -q "bad.conf:2: \[modbus\] coord_scale: expected 1..10000"; then
    ok "bad config rejected with file:line:key"; else fail "bad config: rc=$rc msg=$msg"; fi
printf '[modbus]\nbogus = 1\n' > "$T/bad.conf"
"$IT2ND" -c "$T/bad.conf" --check-config 2>&1 | grep -q "bad.conf:2: \[modbus\] bogus: unknown key" \
    && ok "unknown key rejected" || fail "unknown key accepted"
# (a free port and a scratch state_dir: --check-config also binds the
# listener and writes in state_dir)
"$IT2ND" -c "$ROOT/daemon/it2nd.conf.example" --listen "127.0.0.1:$(free_port)" --state-dir "$T/example.state" \
    --check-config >/dev/null \
    && ok "it2nd.conf.example validates" || fail "it2nd.conf.example does not validate"

# ---- serving, with sd_notify on a test socket -------------------------------
models_conf | write_conf
python3 "$ROOT/tests/daemon/notify_listen.py" "$T/notify.sock" "$T/notify.log" &
NPID=$!
for _ in $(seq 50); do [ -S "$T/notify.sock" ] && break; sleep 0.05; done
NOTIFY_SOCKET=$T/notify.sock WATCHDOG_USEC=200000 start "$IT2ND_SAN"
sleep 0.3
grep -q '^READY=1$' "$T/notify.log" && grep -q '^STATUS=.*models solved' "$T/notify.log" \
    && [ "$(grep -c '^WATCHDOG=1$' "$T/notify.log")" -ge 2 ] \
    && ok "sd_notify READY=1, STATUS=, WATCHDOG=1 every WATCHDOG_USEC/2 (sanitizer build)" \
    || fail "sd_notify: $(cat "$T/notify.log")"
if python3 -c 'import socket; s=socket.socket(socket.AF_INET6); s.bind(("::1", 0))' 2>/dev/null; then
    "$PLC" --tcp "::1:$PORT" read 0 2 >/dev/null && ok "Modbus TCP over IPv6 [::1]" || fail "IPv6 listener"
else echo "e2e: skip: no IPv6 loopback here"; fi

plc verify "$PAPER" 6 && ok "paper data: FC23 queries, grid, control nets match the core" || fail "verify paper"
plc exceptions && ok "exception codes; rejected writes change nothing" || fail "exceptions"
plc concurrent 16 "$PAPER" && ok "16 concurrent connections read their own answers" || fail "concurrent"

# Modbus RTU on the pty pair, served at the same time as TCP.
"$PLC" --rtu "$RTU_B" verify "$PAPER" 3 && "$PLC" --rtu "$RTU_B" exceptions \
    && ok "Modbus RTU: queries, grid, control nets, exceptions" || fail "RTU"
out=$(mbpoll -m rtu -a 1 -0 -r 0 -c 8 -t 3 -b 19200 -P even -1 "$RTU_B" 2>&1)
echo "$out" | grep -q '^\[1\]:[[:space:]]*2$' && ok "mbpoll over RTU" || fail "mbpoll RTU: $out"

# A half-sent request from one client must not stall another.
python3 - "$PORT" <<'PY' &
import socket, sys, time
s = socket.create_connection(("127.0.0.1", int(sys.argv[1])))
s.sendall(bytes([0, 1, 0, 0, 0, 6, 1, 3]))  # 8 of 12 bytes
s.settimeout(3)
t0 = time.time()
closed = s.recv(16) == b""   # the daemon closes it after byte_timeout
sys.exit(0 if closed and 0.3 < time.time() - t0 < 2.5 else 1)
PY
HALF=$!
sleep 0.1
t0=$(date +%s%N)
plc read 0 4 >/dev/null && t1=$(date +%s%N) && [ $(( (t1 - t0) / 1000000 )) -lt 500 ] \
    && ok "half-sent request on another connection does not block ($(( (t1 - t0) / 1000000 )) ms)" \
    || fail "head-of-line blocking"
wait $HALF && ok "half-sent request closed after byte_timeout" || fail "byte timeout"

# max_clients (32): the 33rd..40th connections wait for a slot; each one's
# request takes the slot of the connection idle longest (>= evict_idle), so
# all 40 are served and the first 8 are evicted (docs/daemon.md, slots).
python3 - "$PORT" <<'PY' && ok "max_clients: 40 served in turn, the 8 idle longest evicted" || fail "max_clients"
import socket, struct, sys, time
port = int(sys.argv[1])
socks = [socket.create_connection(("127.0.0.1", port)) for _ in range(40)]
time.sleep(0.2)
served = 0
for k, s in enumerate(socks):
    s.settimeout(2)
    try:
        s.sendall(struct.pack(">HHHBBHH", k, 0, 6, 1, 3, 0, 1))
        served += len(s.recv(64)) == 11
    except OSError:
        pass
closed = []
for k, s in enumerate(socks):
    s.settimeout(0.2)
    try:
        if s.recv(16) == b"":
            closed.append(k)
    except socket.timeout:
        pass
    except OSError:
        closed.append(k)
sys.exit(0 if served == 40 and closed == list(range(8)) else 1)
PY

# Generated data sets from a PLC upload: z model, type-1 model.
plc --unit 4 upload "$ROOT/examples/z_3x3.csv" && plc --unit 4 verify "$ROOT/examples/z_3x3.csv" 4 \
    && ok "z model uploaded over Modbus and verified" || fail "z upload"
plc --unit 3 upload "$ROOT/examples/type1_4x3.csv" && plc --unit 3 verify "$ROOT/examples/type1_4x3.csv" 4 \
    && ok "type-1 model uploaded over Modbus and verified" || fail "type1 upload"

# Generated data sets: degrees 5x4 uploaded by a PLC (reconfigures model 6),
# 6x6 streamed by the instrument below.
python3 "$ROOT/tests/daemon/gen_dataset.py" 5 4 11 2 > "$T/gen54.csv"
python3 "$ROOT/tests/daemon/gen_dataset.py" 6 6 12 > "$T/gen66.csv"
plc --unit 6 upload "$T/gen54.csv" >/dev/null && plc --unit 6 verify "$T/gen54.csv" 5 >/dev/null \
    && ok "generated 5x4 data set: reconfigured, uploaded and verified over Modbus" || fail "generated 5x4"

# mbpoll reads exactly as docs/registers.md shows.
out=$(mbpoll -m tcp -a 1 -0 -r 0 -c 26 -t 3 -1 127.0.0.1 -p $PORT 2>&1)
echo "$out" | grep -q '^\[1\]:[[:space:]]*2$' && echo "$out" | grep -q '^\[6\]:[[:space:]]*112$' \
    && ok "mbpoll FC04 status: state 2, 112 entries" || fail "mbpoll status: $out"
out=$(mbpoll -m tcp -a 1 -0 -r 2048 -c 2 -t 4:float -B -1 127.0.0.1 -p $PORT 2>&1)
echo "$out" | grep -q '^\[2048\]:[[:space:]]*-23$' && echo "$out" | grep -q '^\[2050\]:[[:space:]]*11$' \
    && ok "mbpoll float ABCD control point (-23, 11)" || fail "mbpoll float: $out"
out=$(mbpoll -m tcp -a 1 -0 -r 1024 -c 3 -t 4 -1 127.0.0.1 -p $PORT 2>&1)
echo "$out" | grep -q '^\[1024\]:[[:space:]]*4000$' && echo "$out" | grep -q '^\[1025\]:[[:space:]]*7000$' \
    && ok "mbpoll sample grid node (0,0) = paper data T 0.4, I 0.7" || fail "mbpoll grid: $out"

# pymodbus (Debian python3-pymodbus) following docs/registers.md.
/usr/bin/python3 "$ROOT/tests/daemon/pymodbus_client.py" 127.0.0.1 "$PORT" "$ROOT/build/host/it2n" "$PAPER" \
    && ok "pymodbus client" || fail "pymodbus client"

# ---- instrument links (pty, protocol/ framing) -------------------------------
# The instrument's PUTs carry memberships in Q30 (PUT FINE, docs/protocol.md
# 5.4): a model filled over the link is checked against the CSV as the
# reader holds it, as Modbus uploads and the preload are.
instr --csv "$PAPER" --model 5 --garbage 15 --drop 15 --dup 15 --seed 7 --sample 3 12 9 --net 0 --query 0.25 0.75 \
    && plc --unit 5 verify "$PAPER" 4 >/dev/null \
    && ok "instrument with garbage/drops/duplicates streamed the paper data; SAMPLE/GET_NET/QUERY over the link and Modbus match the core" \
    || fail "instrument stream with faults"
instr --csv "$T/gen66.csv" --model 6 --drop 10 --seed 3 >/dev/null && plc --unit 6 verify "$T/gen66.csv" 4 >/dev/null \
    && ok "generated 6x6 data set streamed by the instrument (CONFIGURE to 6x6) and verified" || fail "generated 6x6 stream"
# A v1.1 instrument (its own session id, fixed first sequence) is still
# served exactly as before, then a v1.2 one with the same numbers.
instr --csv "$PAPER" --model 5 --v11 --session 0x1D --first-seq 77 --drop 10 --seed 4 >/dev/null \
    && plc --unit 5 verify "$PAPER" 4 >/dev/null \
    && instr --csv "$PAPER" --model 5 --first-seq 77 --drop 10 --seed 4 >/dev/null \
    && plc --unit 5 verify "$PAPER" 4 >/dev/null \
    && ok "a v1.1 instrument (session 0x1D) and a v1.2 one (daemon's session) on the same link, both verified" \
    || fail "v1.1 / v1.2 instruments on one link"
# Interleaved: the instrument re-sends every point (REPLACE, incremental
# updates) while a PLC polls the same model and another one.
gen0=$(plc --unit 5 read 7 2 | awk '{print $1 * 65536 + $2}')
instr --csv "$PAPER" --model 5 --no-configure --replace --batch 1 > "$T/instr.out" &
IPID=$!
plc concurrent 8 "$PAPER" >/dev/null && plc --unit 5 verify "$PAPER" 3 >/dev/null; pr=$?
wait $IPID; ir=$?
gen1=$(plc --unit 5 read 7 2 | awk '{print $1 * 65536 + $2}')
if [ $pr = 0 ] && [ $ir = 0 ] && [ "$gen1" -ge $((gen0 + 112)) ]; then
    ok "streaming (112 incremental updates, generation $gen0 -> $gen1) interleaved with polling"
else fail "interleaved streaming/polling: plc $pr instrument $ir gen $gen0 -> $gen1"; fi
# Hang-up mid-stream: Modbus keeps serving, the link reopens with backoff.
instr --csv "$PAPER" --model 5 --hangup-after 20 > /dev/null; hr=$?
plc read 0 2 >/dev/null && [ $hr = 4 ] && ok "instrument hung up; Modbus still serving" || fail "hang-up ($hr)"
instr --csv "$PAPER" --model 5 >/dev/null && plc --unit 5 verify "$PAPER" 3 >/dev/null \
    && ok "link reopened after hang-up, stream completed" || fail "link reopen"
grep -q "link inst: hang-up; reopening" "$T/daemon.log" && ok "hang-up logged, reopen with backoff" || fail "hang-up log"

# ---- one daemon per device ----------------------------------------------------
# A second it2nd naming the same serial device (a link on a pty pair, the
# RTU bus held by the first daemon) must not open it: both would read the
# frames and answer (bug: a stray daemon reopening a vanished /dev/pts/N
# answered another test's instrument with its own models).
"$PTY" > "$T/pty2" &
LBPID=$!
for _ in $(seq 50); do [ -s "$T/pty2" ] && break; sleep 0.02; done
read -r LNK_A LNK_B < "$T/pty2"
two_conf() { # name port
    mkdir -p "$T/$1"
    printf '[daemon]\nstate_dir = %s\nlink_backoff_max = 1\n[modbus]\ntcp_listen = 127.0.0.1:%s\n' "$T/$1" "$2"
    printf '[rtu:bus]\ndevice = %s\nbaud = 19200\n' "$RTU_A"
    printf '[model:1]\nunit_id = 1\nn = 3\nm = 3\n[link:x]\ntype = serial\ndevice = %s\nbaud = 115200\n' "$LNK_A"
}
P2=$(free_port); P3=$(free_port)
two_conf d2 "$P2" > "$T/d2.conf"; two_conf d3 "$P3" > "$T/d3.conf"
"$IT2ND" -c "$T/d2.conf" -f -v > "$T/d2.log" 2>&1 & D2=$!
for _ in $(seq 100); do grep -q "link x: open" "$T/d2.log" && break; sleep 0.05; done
"$IT2ND" -c "$T/d3.conf" -f -v > "$T/d3.log" 2>&1 & D3=$!
for _ in $(seq 100); do grep -q "link x: device locked" "$T/d3.log" && break; sleep 0.05; done
grep -q "link x: device locked by another process" "$T/d3.log" \
    && grep -q "rtu bus.*device locked by another process" "$T/d3.log" \
    && grep -q "rtu bus.*device locked by another process" "$T/d2.log" \
    && ! grep -q "link x: open" "$T/d3.log" \
    && ok "a second and third it2nd on the same link / RTU device: not opened, 'device locked by another process' logged" \
    || fail "device lock: $(grep -h 'link x\|rtu bus' "$T/d2.log" "$T/d3.log" | head -5)"
timeout 30 "$EXINSTR" --device "$LNK_B" --model 1 --degree 3x3 --seed 5 --quiet > "$T/ex.out" 2>&1; xr=$?
plc read 0 1 >/dev/null && "$PLC" --tcp 127.0.0.1:$P2 --unit 1 read 0 1 > /dev/null \
    && [ $xr = 0 ] && grep -q "link x: HELLO from" "$T/d2.log" && ! grep -q "HELLO from" "$T/d3.log" \
    && ok "the instrument on that link was served by the daemon holding it, once; the first daemon's RTU bus kept serving" \
    || fail "served by the lock holder: instrument rc $xr $(cat "$T/ex.out"); d3: $(grep HELLO "$T/d3.log" | head -2)"
out=$(mbpoll -m rtu -a 1 -0 -r 0 -c 8 -t 3 -b 19200 -P even -1 "$RTU_B" 2>&1)
echo "$out" | grep -q '^\[1\]:[[:space:]]*2$' && ok "RTU still answered by the first daemon alone (mbpoll)" || fail "RTU after the refused daemons: $out"
kill "$D2" "$D3" "$LBPID"; wait "$D2" "$D3" "$LBPID" 2>/dev/null

# ---- EVENTs to link peers ---------------------------------------------------
# A passive peer on a second pty logs every EVENT ("model kind code gen").
gen() { plc --unit "${1:-1}" read 7 2 | awk '{print $1 * 65536 + $2}'; }
last_ev() { # model: the last EVENT line of that model
    awk -v m="$1" '$1 == m' "$T/events" 2>/dev/null | tail -n1
}
wait_ev() { # model "kind code gen"
    for _ in $(seq 100); do [ "$(last_ev "$1" | cut -d' ' -f2-)" = "$2" ] && return 0; sleep 0.05; done
    return 1
}
: > "$T/events"
rm -f "$T/inst0"   # every instrument run so far has ended
"$INSTR" --link "$T/ev0" --events "$T/events" --timeout 120 > /dev/null 2>&1 &
EPID=$!
for _ in $(seq 100); do grep -q "link ev: HELLO from 'sim-peer'" "$T/daemon.log" && break; sleep 0.05; done
instr --csv "$PAPER" --model 5 --no-configure --replace --batch 4 > /dev/null; ir=$?
g5=$(gen 5)
if [ $ir = 0 ] && wait_ev 5 "3 0 $g5" && awk '$1 == 5 && $2 == 2' "$T/events" | grep -q .; then
    ok "peer got EVENTs for an instrument's PUTs (UPDATED) and COMMIT (SOLVED, generation $g5)"
else fail "EVENTs for link PUTs: rc $ir, gen $g5, last: $(last_ev 5)"; fi
n5=$(awk '$1 == 5' "$T/events" | wc -l)
[ "$n5" -le 29 ] && ok "at most one EVENT per model and loop pass ($n5 for 28 PUTs + COMMIT)" \
    || fail "EVENTs not coalesced: $n5"
plc write 40 0 0 3 65535 63836 0 1700 0 0 4000 7000 2000 > /dev/null
g1=$(gen)
wait_ev 1 "2 0 $g1" && ok "peer got an EVENT for a PLC write over Modbus (model 1 UPDATED, generation $g1)" \
    || fail "EVENT for a Modbus write: want '1 2 0 $g1', last '$(last_ev 1)'"
# Kinds: a Modbus CLEAR command is RESET, a new configuration CONFIGURED.
plc --unit 6 write 35 2 > /dev/null; g6=$(gen 6)
wait_ev 6 "4 0 $g6" && ok "EVENT RESET for a CLEAR command (model 6, generation $g6)" \
    || fail "EVENT RESET: want '6 4 0 $g6', last '$(last_ev 6)'"
plc --unit 6 write 32 2 2 0 > /dev/null; g6=$(gen 6)
wait_ev 6 "1 0 $g6" && ok "EVENT CONFIGURED for a new configuration over Modbus (generation $g6)" \
    || fail "EVENT CONFIGURED: want '6 1 0 $g6', last '$(last_ev 6)'"
# A peer that stops reading must not stall the loop; it gets the latest.
kill -STOP $EPID
t0=$(date +%s%N)
for v in 4100 4200 4300 4400 4500 4600 4700 4800 4900 4000; do
    plc write 40 0 0 3 65535 63836 0 1700 0 0 $v 7000 2000 > /dev/null || fail "write while the peer sleeps"
done
t1=$(date +%s%N)
g1=$(gen)
kill -CONT $EPID
ms=$(( (t1 - t0) / 1000000 ))
[ $ms -lt 2000 ] && ok "10 writes in $ms ms while the peer is stopped" || fail "stalled by a stopped peer: $ms ms"
wait_ev 1 "2 0 $g1" && ok "stopped peer resumed and got the latest EVENT (generation $g1)" \
    || fail "latest EVENT after resume: want '1 2 0 $g1', last '$(last_ev 1)'"
kill $EPID 2>/dev/null; wait $EPID 2>/dev/null

# ---- SIGHUP reload keeps live connections -----------------------------------
python3 - "$PORT" "$PID" "$T" <<'PY' && ok "SIGHUP: word order changed, live connection kept" || fail "SIGHUP reload"
import os, signal, socket, struct, sys, time
port, pid, tdir = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
s = socket.create_connection(("127.0.0.1", port))
def read(addr, n, tid=[0]):
    tid[0] += 1
    s.sendall(struct.pack(">HHHBBHH", tid[0], 0, 6, 1, 3, addr, n))
    hdr = s.recv(9)
    body = s.recv(hdr[8])
    return struct.unpack(">%dH" % n, body)
assert read(21, 1) == (0,)
conf = open(tdir + "/it2nd.conf").read()
# Floats CDAB, integers kept high word first (the rest of this script reads
# generations that way; int32 following CDAB, the default, is interop-modbus's).
open(tdir + "/it2nd.conf", "w").write(conf.replace("[modbus]\n", "[modbus]\nfloat_word_order = CDAB\nint32_word_order = ABCD\n"))
os.kill(pid, signal.SIGHUP)
for _ in range(40):
    time.sleep(0.05)
    if read(21, 1) == (1,):
        break
assert read(21, 1) == (1,), "word order not reloaded"
assert read(27, 1) == (0,), "int32_word_order not reloaded"
PY
plc verify "$PAPER" 3 >/dev/null && ok "CDAB word order verified after reload" || fail "verify CDAB"

# ---- crash: kill -9 mid-stream, nothing acknowledged is lost ----------------
plc --unit 2 stream "$PAPER" "$T/acked" &
SPID=$!
for _ in $(seq 200); do [ "$(wc -l < "$T/acked" 2>/dev/null || echo 0)" -ge 30 ] && break; sleep 0.01; done
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=
wait $SPID
acked=$(tail -n1 "$T/acked" 2>/dev/null || echo 0)
start "$IT2ND"
present=$(plc --unit 2 read 5 1)
if [ "$present" -ge "$acked" ] && [ "$present" -le $((acked + 1)) ]; then
    ok "kill -9 after $acked acknowledged points: $present present after restart"
else fail "kill -9: acked $acked, present $present"; fi
plc --unit 4 verify "$ROOT/examples/z_3x3.csv" 3 >/dev/null && plc --unit 3 verify "$ROOT/examples/type1_4x3.csv" 3 >/dev/null \
    && ok "models survive kill -9 (WAL replay)" || fail "models lost after kill -9"
plc --unit 2 upload "$PAPER" && plc --unit 2 verify "$PAPER" 3 >/dev/null \
    && ok "stream completed after restart" || fail "complete after restart"

# kill -9 while an instrument streams: every ACKed entry survives.
# (timeout itself in the background, not the instr function's subshell:
# killing that left the instrument streaming into the restarted daemon)
timeout 60 "$INSTR" --link "$T/inst0" --csv "$PAPER" --model 5 --batch 2 --ack-log "$T/iacked" > /dev/null 2>&1 &
IPID=$!
for _ in $(seq 300); do [ "$(tail -n1 "$T/iacked" 2>/dev/null)" -ge 30 ] 2>/dev/null && break; sleep 0.01; done
kill -9 "$PID"; wait "$PID" 2>/dev/null; PID=
kill "$IPID" 2>/dev/null; wait "$IPID" 2>/dev/null
iacked=$(tail -n1 "$T/iacked" 2>/dev/null || echo 0)
start "$IT2ND"
present=$(plc --unit 5 read 5 1)
if [ "$iacked" -ge 1 ] && [ "$present" -ge "$iacked" ] && [ "$present" -le $((iacked + 8)) ]; then
    ok "kill -9 during instrument stream: $iacked entries ACKed, $present present after restart"
else fail "instrument kill -9: acked $iacked present $present"; fi
instr --csv "$PAPER" --model 5 >/dev/null && plc --unit 5 verify "$PAPER" 3 >/dev/null \
    && ok "instrument re-stream after restart" || fail "re-stream after restart"

# Clean stop writes a snapshot; restart from it.
stop TERM && ok "SIGTERM: clean exit" || fail "SIGTERM exit status"
[ -s "$STATE/snapshot" ] && ok "snapshot written on stop" || fail "no snapshot"
start "$IT2ND"
plc --unit 2 verify "$PAPER" 3 >/dev/null && plc --unit 4 verify "$ROOT/examples/z_3x3.csv" 3 >/dev/null \
    && ok "restart from snapshot" || fail "restart from snapshot"

# ---- a failed group commit changes nothing ----------------------------------
# failsync.so makes fsync/fdatasync fail with EIO while $T/failsync exists.
UP_D00="0 0 3 65535 63836 0 1700 0 0"   # upload: i j fp, x -17.00, y 17.00, z 0
stop TERM
LD_PRELOAD=$FAILSYNC IT2N_FAILSYNC_FLAG=$T/failsync start "$IT2ND"
out=$(plc write 40 $UP_D00 4500 7000 2000)
g1=$(gen); v1=$(plc read 1024 1); g5=$(gen 5)
[ "$out" = ok ] && [ "$v1" = 4500 ] && ok "write T(0,0,D) = 0.45 answered OK, served (generation $g1)" \
    || fail "write before the disk failure: $out, grid $v1"
touch "$T/failsync"
out=$(plc write 40 $UP_D00 5500 7000 2000); rc=$?
v2=$(plc read 1024 1); g2=$(gen); up=$(plc read 40 12 | awk '{print $10}')
if [ $rc = 3 ] && [ "$out" = "exception 4" ] && [ "$v2" = 4500 ] && [ "$g2" = "$g1" ] && [ "$up" = 4500 ]; then
    ok "fsync fails: exception 04, value, generation and upload echo unchanged"
else fail "failed commit: rc $rc '$out', grid $v2 gen $g1 -> $g2, upload T $up"; fi
grep -q "wal: write failed: Input/output error" "$T/daemon.log" && ok "failed commit logged" || fail "no log of the failed commit"
instr --csv "$PAPER" --model 5 --no-configure --replace --batch 4 > "$T/nack.out" 2>&1; rc=$?
g5b=$(gen 5)
[ $rc = 1 ] && grep -qE "PUT seq .* refused: -20[02] " "$T/nack.out" && [ "$g5b" = "$g5" ] \
    && plc --unit 5 verify "$PAPER" 3 >/dev/null \
    && ok "instrument PUT NACKed while fsync fails; model 5 unchanged (generation $g5)" \
    || fail "instrument PUT on a failing disk: rc $rc gen $g5 -> $g5b: $(cat "$T/nack.out")"
# The store is degraded after the failed commit: writes are refused until a
# checkpoint (snapshot + new WAL) succeeds, retried every second.
from=$(($(wc -l < "$T/daemon.log") + 1))
rm -f "$T/failsync"
for _ in $(seq 100); do tail -n +"$from" "$T/daemon.log" | grep -q "store: checkpoint written" && break; sleep 0.05; done
out=$(plc write 40 $UP_D00 6000 7000 2000)
v3=$(plc read 1024 1); g3=$(gen)
[ "$out" = ok ] && [ "$v3" = 6000 ] && [ "$g3" = $((g1 + 1)) ] \
    && ok "disk back: write OK, served, generation $g3" || fail "after recovery: $out grid $v3 gen $g3"
stop KILL
start "$IT2ND"
v4=$(plc read 1024 1); g4=$(gen); g5c=$(gen 5)
[ "$v4" = 6000 ] && [ "$g4" = "$g3" ] && [ "$g5c" = "$g5" ] \
    && ok "restart after kill -9: exactly the acknowledged state (T 0.6, generation $g4)" \
    || fail "restart after failed commits: grid $v4 gen $g4 (want 6000 $g3), model 5 gen $g5c (want $g5)"
out=$(plc write 40 0 0 3 65535 63836 0 1700 0 0 4000 7000 2000)   # paper value back

# ---- corrupted files ----------------------------------------------------------
plc --unit 2 upload "$ROOT/examples/paper_4x4.csv" >/dev/null   # WAL records after the snapshot
stop KILL
printf 'garbage' >> "$STATE/wal"
start "$IT2ND"
grep -q "wal: truncated record" "$T/daemon.log" && plc --unit 2 verify "$PAPER" 3 >/dev/null \
    && ok "garbage tail of the WAL dropped and reported, data kept" || fail "wal garbage"
stop KILL
cp -a "$STATE" "$T/state.backup"   # the operator's backup (snapshot + WAL)
python3 -c "
import sys; p=sys.argv[1]; b=bytearray(open(p,'rb').read()); b[len(b)//2]^=0xFF; open(p,'wb').write(b)" "$STATE/snapshot"
timeout 20 "$IT2ND_SAN" -c "$T/it2nd.conf" -f >> "$T/daemon.log" 2>&1; rc=$?
[ $rc = 1 ] && grep -q "snapshot is damaged (checksum or structure): kept as $STATE/snapshot.damaged-" "$T/daemon.log" \
    && [ ! -e "$STATE/snapshot" ] \
    && ok "corrupted snapshot kept aside, start refused: no state that never existed served (sanitizer build)" \
    || fail "corrupt snapshot: rc $rc"
rm -rf "$STATE"; cp -a "$T/state.backup" "$STATE"   # recovery: the backup back
start "$IT2ND_SAN"
plc verify "$PAPER" 3 >/dev/null && plc --unit 3 verify "$ROOT/examples/type1_4x3.csv" 3 >/dev/null \
    && ok "state restored from the backup after a bad snapshot" || fail "after bad snapshot"
stop TERM || fail "sanitizer build exit status"

# ---- SIGHUP applies model changes, the TCP connection stays open ---------------
# Remove model 6, add model 7 (paper preload), move model 3 from unit 3 to
# unit 13, reconfigure model 4 from 2x2 (z) to 3x3 (z).
start "$IT2ND_SAN"
# (model 3's data again, as a PLC would after a restore)
plc --unit 3 upload "$ROOT/examples/type1_4x3.csv" >/dev/null || fail "type-1 upload before the model reload"
# A WAL record of model 6, which the reload removes.
[ "$(plc --unit 6 write 40 0 0 3 65535 63836 0 1700 0 0 4000 7000 2000)" = ok ] || fail "write to model 6"
python3 - "$PORT" "$PID" "$T" <<'PY' && ok "SIGHUP on one open connection: model 7 added, model 6 removed, model 3 on unit 13, model 4 reconfigured 3x3" || fail "SIGHUP model changes"
import os, signal, socket, struct, sys, time
port, pid, tdir = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
s = socket.create_connection(("127.0.0.1", port))
s.settimeout(3)
tid = 0
def read(unit, addr, n):
    global tid
    tid += 1
    s.sendall(struct.pack(">HHHBBHH", tid, 0, 6, unit, 3, addr, n))
    hdr = s.recv(9)
    if hdr[7] & 0x80:
        return ("exc", hdr[8])
    body = b""
    while len(body) < hdr[8]:
        body += s.recv(hdr[8] - len(body))
    return struct.unpack(">%dH" % n, body)
assert read(3, 1, 1) == (2,), read(3, 1, 1)          # type-1 model solved on unit 3
assert read(6, 1, 1) != ("exc", 0x0B)
assert read(7, 1, 1) == ("exc", 0x0B)                # no model on unit 7 yet
assert read(4, 32, 3) == (2, 2, 1), read(4, 32, 3)
c = open(tdir + "/it2nd.conf").read()
# model 6 holds data: its removal is explicit (removed = yes), never a
# side effect of a section gone from the file.
c = c.replace("[model:6]\nunit_id = 6\nn = 2\nm = 2\n", "[model:6]\nremoved = yes\n[model:7]\nunit_id = 7\npreload = paper\n")
c = c.replace("[model:3]\nunit_id = 3\n", "[model:3]\nunit_id = 13\n")
c = c.replace("[model:4]\nunit_id = 4\nn = 2\nm = 2\n", "[model:4]\nunit_id = 4\nn = 3\nm = 3\n")
open(tdir + "/it2nd.conf", "w").write(c)
os.kill(pid, signal.SIGHUP)
for _ in range(60):
    time.sleep(0.05)
    if read(7, 1, 1) == (2,):
        break
assert read(7, 1, 1) == (2,), "model 7 not added"
assert read(6, 1, 1) == ("exc", 0x0B), "model 6 not removed"
assert read(3, 1, 1) == ("exc", 0x0B), "unit 3 still mapped"
assert read(13, 1, 1) == (2,), "model 3 not on unit 13"
assert read(4, 32, 3) == (3, 3, 1) and read(4, 1, 1) == (0,), "model 4 not reconfigured"
PY
plc --unit 13 verify "$ROOT/examples/type1_4x3.csv" 3 >/dev/null && plc --unit 7 verify "$PAPER" 3 >/dev/null \
    && ok "after the reload: unit 13 serves model 3's data, unit 7 the paper data" || fail "data after the model reload"
grep -q "reload: model 4 reconfigured to 3x3, flags 1: points cleared (journaled CONFIGURE)" "$T/daemon.log" \
    && grep -q "reload: model 6 (unit 6) removed (removed = yes); its 1 data point(s) are discarded" "$T/daemon.log" \
    && ok "reconfigure and removal logged" || fail "reload log lines"
stop KILL   # no snapshot at exit: only the one the reload took
start "$IT2ND"
plc --unit 13 verify "$ROOT/examples/type1_4x3.csv" 3 >/dev/null && plc --unit 7 verify "$PAPER" 3 >/dev/null \
    && [ "$(plc --unit 4 read 32 2)" = "3 3" ] && ! plc --unit 6 read 0 1 >/dev/null 2>&1 \
    && [ "$(sed -n '/reload: model 6/,$p' "$T/daemon.log" | grep -c "model 6.*\(no longer\|dropped\)")" = 0 ] \
    && ok "kill -9 and restart after the reload: same models, no record of model 6 left to replay" \
    || fail "restart after the model reload"
stop TERM

# ---- RS-485 options on a pty (no RS-485 mode, no RTS line) ------------------
# The device refuses: a warning naming device and option, RS-232 served; with
# rs485_strict = yes the port is not served (TCP goes on). Reloaded by SIGHUP.
"$PTY" > "$T/pty485" &
BPID485=$!
for _ in $(seq 50); do [ -s "$T/pty485" ] && break; sleep 0.02; done
read -r RS_A RS_B < "$T/pty485"
rs485_conf() { # [rtu:rs] RS-485 lines on stdin
    {
        printf '[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\n' "$T/state485"
        printf '[modbus]\ntcp_listen = 127.0.0.1:%s\n[model:1]\nunit_id = 1\npreload = paper\n' "$PORT"
        printf '[rtu:rs]\ndevice = %s\nbaud = 19200\nrs485 = yes\n' "$RS_A"
        cat
    } > "$T/rs485.conf"
}
log_wait() { # grep -E pattern: up to 5 s for it in the daemon log
    for _ in $(seq 100); do grep -qE "$1" "$T/daemon.log" && return 0; sleep 0.05; done
    return 1
}
mbpoll_rs() { mbpoll -m rtu -a 1 -0 -r 0 -c 8 -t 3 -b 19200 -P even -o 0.5 -1 "$RS_B" 2>&1; }
printf 'rs485_rts_on_send = low\nrs485_delay_before_send_ms = 1\nrs485_delay_after_send_ms = 2\n' | rs485_conf
"$IT2ND" -c "$T/rs485.conf" --check-config >/dev/null || fail "rs485.conf does not validate"
CONF=$T/rs485.conf start "$IT2ND_SAN"
log_wait "rtu rs: $RS_A refuses RS-485 mode \(rs485 = yes, TIOCSRS485\): .*; serving in RS-232 mode" \
    && log_wait "modbus rtu rs on $RS_A, 19200 E1, RS-232 \(RS-485 refused\)" \
    && ok "rs485 = yes + kernel options on a pty: warning names device and option" \
    || fail "no RS-485 refusal warning"
out=$(mbpoll_rs)
echo "$out" | grep -q '^\[1\]:[[:space:]]*2$' && "$PLC" --rtu "$RS_B" verify "$PAPER" 3 \
    && ok "RS-485 refused: RTU still served in RS-232 mode (mbpoll, PLC)" || fail "RTU after RS-485 refusal: $(echo "$out" | tail -3)"
printf 'rs485_rts = up\nrs485_rts_delay_us = 500\n' | rs485_conf
kill -HUP "$PID"
log_wait "rtu rs: $RS_A refuses RTS control \(rs485_rts = up, TIOCMGET\): .*; serving in RS-232 mode" \
    && out=$(mbpoll_rs) && echo "$out" | grep -q '^\[1\]:[[:space:]]*2$' \
    && ok "SIGHUP to rs485_rts = up: no RTS line on a pty, warned, RTU still served" \
    || fail "rs485_rts on a pty: $(echo "$out" | tail -3)"
printf 'rs485_strict = yes\n' | rs485_conf
kill -HUP "$PID"
log_wait "rtu rs: $RS_A refuses RS-485 mode .*; not served \(rs485_strict = yes\)" \
    && log_wait "rtu rs \($RS_A\): RS-485 set-up refused; reopening" \
    && ! mbpoll_rs | grep -q '^\[1\]:' && [ "$(plc read 1024 1)" != "" ] \
    && ok "rs485_strict = yes: port refused (retried with backoff), TCP still served" \
    || fail "rs485_strict"
stop TERM || fail "exit status after the RS-485 tests (sanitizer build)"
kill "$BPID485" 2>/dev/null; wait "$BPID485" 2>/dev/null; BPID485=
printf '[rtu:a]\ndevice = /dev/null\nrs485_rts = up\n' > "$T/bad.conf"
"$IT2ND" -c "$T/bad.conf" --check-config 2>&1 | grep -q "bad.conf:3: \[rtu:a\] rs485_rts: needs rs485 = yes in this section" \
    && ok "RS-485 option without rs485 = yes: file:line error" || fail "rs485_rts without rs485 accepted"

# ---- privilege drop (user = nobody) ------------------------------------------
if [ "$(id -u)" != 0 ]; then
    echo "e2e: skip: privilege drop test needs root (running as uid $(id -u))"
elif ! id nobody >/dev/null 2>&1; then
    echo "e2e: skip: no user 'nobody' on this system"
else
    printf '[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\nuser = nobody\n[modbus]\ntcp_listen = 127.0.0.1:%s\n[model:1]\nunit_id = 1\npreload = paper\n' \
        "$T/state_nobody" "$PORT" > "$T/nobody.conf"
    CONF=$T/nobody.conf start "$IT2ND_SAN"
    nu=$(id -u nobody); ng=$(id -g nobody)
    uids=$(awk '/^Uid:/ {print $2, $3, $4, $5}' /proc/$PID/status)
    gids=$(awk '/^Gid:/ {print $2, $3, $4, $5}' /proc/$PID/status)
    grps=$(awk '/^Groups:/ {$1 = ""; print}' /proc/$PID/status | xargs -n1 | sort -n | xargs)
    want_grps=$(id -G nobody | xargs -n1 | sort -n | xargs)
    [ "$uids" = "$nu $nu $nu $nu" ] && [ "$gids" = "$ng $ng $ng $ng" ] && [ "$grps" = "$want_grps" ] \
        && grep -q "running as user nobody (uid $nu, gid $ng)" "$T/daemon.log" \
        && ok "user = nobody: /proc Uid $uids, Gid $gids, groups '$grps' (sanitizer build)" \
        || fail "privilege drop: Uid '$uids' Gid '$gids' Groups '$grps' (want $nu, $ng, '$want_grps')"
    [ "$(stat -c %U "$T/state_nobody")" = nobody ] && ok "state directory given to nobody" \
        || fail "state directory owner $(stat -c %U "$T/state_nobody")"
    out=$(plc write 40 0 0 3 65535 63836 0 1700 0 0 4400 7000 2000)
    [ "$out" = ok ] && plc read 0 1 >/dev/null && [ "$(plc read 1024 1)" = 4400 ] \
        && ok "Modbus serves and accepts writes as nobody" || fail "Modbus as nobody: $out"
    stop TERM && [ -s "$T/state_nobody/snapshot" ] && [ "$(stat -c %U "$T/state_nobody/snapshot")" = nobody ] \
        && ok "SIGTERM as nobody: clean exit, fresh snapshot owned by nobody" \
        || fail "snapshot as nobody: $(ls -l "$T/state_nobody" 2>&1)"
    CONF=$T/nobody.conf start "$IT2ND"
    [ "$(plc read 1024 1)" = 4400 ] && ok "restart from the snapshot written as nobody" || fail "restart as nobody"
    stop TERM
    printf '[daemon]\nuser = it2n-no-such-user\n' > "$T/nouser.conf"
    "$IT2ND" -c "$T/nouser.conf" --check-config 2>&1 | grep -q "nouser.conf:2: \[daemon\] user: unknown user 'it2n-no-such-user'" \
        && ok "unknown user: fatal config error with file:line" || fail "unknown user accepted"
fi

tl_finish "$T/daemon.log" 50
