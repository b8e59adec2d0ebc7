#!/bin/bash
# it2nd's flags for the common case and its operator errors (issue 18 items
# 2 and 4), driven on the real binary over loopback TCP:
#  * it2nd --listen HOST:PORT --state-dir DIR (--metrics) without a file
#    serves there and keeps its state there; over a file the flags win
#    (the file's listener and state_dir are not used); make run PORT= STATE=
#    passes the same flags;
#  * --check-config: a state directory the daemon cannot create or write
#    (run as an unprivileged user when root), a path through a file, a port
#    held by another process (named, with its pid) exit 1 and change
#    nothing; with the daemon itself running on the same state_dir its
#    ports are a warning and the check exits 0;
#  * the daemon on a port in use says who holds it and what to do;
#  * config typos: "did you mean", a line without '='.
# Env: IT2ND (path).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
IT2ND=$(realpath "$IT2ND")
. "$ROOT/tests/lib/testlib.sh"
tl_init flags it2nd-flags
PY=/usr/bin/python3
PIDS=()

tl_on_exit() {
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null; done
    wait 2>/dev/null
}
serves() { # port: the status block answers over Modbus TCP (unit 1)
    $PY - "$1" <<'EOF'
import sys
from pymodbus.client import ModbusTcpClient
c = ModbusTcpClient("127.0.0.1", port=int(sys.argv[1]), timeout=2)
ok = c.connect() and not c.read_input_registers(0, 2, slave=1).isError()
c.close()
sys.exit(0 if ok else 1)
EOF
}
start() { # log args...: start it2nd in the background, PID in $PID
    local log=$1
    shift
    "$IT2ND" -f "$@" > "$log" 2>&1 &
    PID=$!
    PIDS+=("$PID")
}
stop() { kill "$1" 2>/dev/null; wait "$1" 2>/dev/null; }

P1=$(free_port)
P2=$(free_port)
PM=$(free_port)

# 1. Flags without a configuration file.
cd "$T" || exit 1
start "$T/d1.log" --listen "127.0.0.1:$P1" --state-dir ./state2 --metrics "127.0.0.1:$PM"
if wait_port "$P1" && serves "$P1"; then ok "--listen 127.0.0.1:$P1: Modbus served there"; else fail "--listen: not served"; fi
[ -f "$T/state2/wal" ] && ok "--state-dir ./state2: WAL in ./state2" || fail "--state-dir: no ./state2/wal"
[ ! -e "$T/state" ] && ok "the default ./state is not used" || fail "./state created"
if $PY -c "import urllib.request,sys; t=urllib.request.urlopen('http://127.0.0.1:$PM/metrics',timeout=5).read().decode(); sys.exit(0 if 'it2nd_model_solved{model=\"1\"} 1' in t else 1)"; then
    ok "--metrics 127.0.0.1:$PM: /metrics served"
else fail "--metrics: /metrics not served"; fi

# 2. --check-config while that daemon runs on the same state_dir: its own
# ports are a warning, not an error.
out=$("$IT2ND" --listen "127.0.0.1:$P1" --state-dir ./state2 --metrics "127.0.0.1:$PM" --check-config 2>&1)
rc=$?
if [ $rc = 0 ] && grep -q "in use by it2nd (pid $PID) while a running it2nd holds ./state2/lock" <<<"$out" &&
   grep -q "configuration OK" <<<"$out"; then
    ok "--check-config beside the running daemon: exit 0, its ports a warning"
else fail "--check-config beside the daemon: rc $rc: $out"; fi

# 3. Another state_dir, same port: the port is an error naming the holder.
out=$("$IT2ND" --listen "127.0.0.1:$P1" --state-dir "$T/other" --check-config 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "127.0.0.1:$P1 is in use by it2nd (pid $PID); stop that process or choose another port (it2nd --listen HOST:PORT" <<<"$out"; then
    ok "--check-config with a port held by another daemon: exit 1, names it2nd (pid $PID)"
else fail "--check-config port in use: rc $rc: $out"; fi
[ ! -e "$T/other" ] && ok "--check-config left no state directory behind" || fail "--check-config created $T/other"

# 4. The daemon itself on a port in use: the hint, exit non-zero.
"$IT2ND" -f --listen "127.0.0.1:$P1" --state-dir "$T/s4" > "$T/d4.log" 2>&1
rc=$?
if [ $rc != 0 ] && grep -q "Address already in use: 127.0.0.1:$P1 is in use by it2nd (pid $PID); stop that process or choose another port" "$T/d4.log"; then
    ok "start on a port in use: exit $rc, names the holder and what to do"
else fail "start on a port in use: rc $rc: $(cat "$T/d4.log")"; fi
# a port held by something else (python): named too
$PY -c "import socket,time; s=socket.socket(); s.bind(('127.0.0.1',$P2)); s.listen(1); time.sleep(30)" &
HOLDER=$!
PIDS+=("$HOLDER")
wait_port "$P2"
out=$("$IT2ND" --listen "127.0.0.1:$P2" --state-dir "$T/s5" -t 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "is in use by python3 (pid $HOLDER)" <<<"$out"; then
    ok "--check-config names another program holding the port (python3, pid $HOLDER)"
else fail "--check-config other holder: rc $rc: $out"; fi
out=$("$IT2ND" --listen "127.0.0.1:$(free_port)" --metrics "127.0.0.1:$P2" --state-dir "$T/s5" -t 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "metrics listen: 127.0.0.1:$P2 is in use by python3 (pid $HOLDER); stop that process or choose another port (it2nd --metrics HOST:PORT, or \[metrics\] listen)" <<<"$out"; then
    ok "--check-config: metrics port in use named too"
else fail "--check-config metrics port: rc $rc: $out"; fi
stop "$HOLDER"
stop "$PID"

# 5. Flags override a file: its listener and state_dir are not used.
cat > "$T/f.conf" <<EOF
[daemon]
state_dir = $T/file-state
[modbus]
tcp_listen = 127.0.0.1:$P2
EOF
start "$T/d5.log" -c "$T/f.conf" --listen "127.0.0.1:$P1" --state-dir "$T/flag-state"
if wait_port "$P1" && serves "$P1"; then ok "flags over a file: served on --listen"; else fail "flags over a file: not on --listen"; fi
# a file whose listener has an access policy: the replacement is logged
printf '[listen:plc]\naddress = 127.0.0.1:%s\nallow = 10.0.0.0/8\n' "$P2" > "$T/acl.conf"
out=$("$IT2ND" -c "$T/acl.conf" --listen "127.0.0.1:$(free_port)" --state-dir "$T/acl-state" -t 2>&1)
grep -q "listen replaces the listeners of $T/acl.conf, 1 of them with an access policy (allow, read_only): the --listen address has none" <<<"$out" &&
    ok "--listen over a listener with an allow list: a warning says so" || fail "--listen over an ACL: $out"
if ! $PY -c "import socket; socket.create_connection(('127.0.0.1',$P2),0.5)" 2>/dev/null; then
    ok "the file's tcp_listen is not opened"
else fail "the file's tcp_listen was opened"; fi
[ -f "$T/flag-state/wal" ] && [ ! -e "$T/file-state" ] && ok "--state-dir over the file's state_dir" ||
    fail "--state-dir over a file"
stop "$PID"

# 6. --check-config: a state directory the daemon cannot write.
if [ "$(id -u)" = 0 ] && command -v setpriv >/dev/null; then
    AS=(setpriv --reuid=65534 --regid=65534 --clear-groups)
    chmod 755 "$T"                          # nobody may look inside
    mkdir -p "$T/ro" && chmod 755 "$T/ro"   # root's: nobody cannot write it
    WHO="nobody (setpriv)"
else
    AS=()
    mkdir -p "$T/ro" && chmod 555 "$T/ro"
    WHO="$(id -un)"
fi
out=$("${AS[@]}" "$IT2ND" --listen "127.0.0.1:$(free_port)" --state-dir "$T/ro" -t 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "state_dir $T/ro: not writable (creating a file: Permission denied)" <<<"$out"; then
    ok "--check-config as $WHO: an existing state_dir it cannot write: exit 1"
else fail "--check-config unwritable state_dir: rc $rc: $out"; fi
out=$("${AS[@]}" "$IT2ND" --listen "127.0.0.1:$(free_port)" --state-dir "$T/ro/sub" -t 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "state_dir $T/ro/sub: cannot be created: Permission denied" <<<"$out"; then
    ok "--check-config as $WHO: a state_dir it cannot create: exit 1"
else fail "--check-config uncreatable state_dir: rc $rc: $out"; fi
# the daemon agrees: it cannot start there either
"${AS[@]}" "$IT2ND" -f --listen "127.0.0.1:$(free_port)" --state-dir "$T/ro/sub" > "$T/d6.log" 2>&1
rc=$?
if [ $rc != 0 ] && [ $rc != 127 ] && grep -q "Permission denied" "$T/d6.log"; then
    ok "... and the daemon indeed cannot start there (exit $rc: $(grep -m1 'Permission denied' "$T/d6.log"))"
else fail "the daemon on a state_dir --check-config refused: rc $rc: $(cat "$T/d6.log")"; fi
touch "$T/afile"
out=$("$IT2ND" --listen "127.0.0.1:$(free_port)" --state-dir "$T/afile/x" -t 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "state_dir $T/afile/x: Not a directory" <<<"$out"; then
    ok "--check-config: a state_dir under a file: exit 1"
else fail "--check-config state_dir under a file: rc $rc: $out"; fi
out=$("$IT2ND" --listen "127.0.0.1:$(free_port)" --state-dir "$T/new/a" -t 2>&1)
rc=$?
if [ $rc = 1 ] && grep -q "its parent directory does not exist" <<<"$out" && [ ! -e "$T/new" ]; then
    ok "--check-config: a state_dir whose parent is missing: exit 1 (the daemon makes one level)"
else fail "--check-config missing parent: rc $rc: $out"; fi
out=$("$IT2ND" --listen "127.0.0.1:$(free_port)" --state-dir "$T/new" -t 2>&1)
rc=$?
if [ $rc = 0 ] && [ ! -e "$T/new" ]; then
    ok "--check-config: a creatable state_dir is OK and left uncreated"
else fail "--check-config creatable state_dir: rc $rc: $out; $(ls "$T")"; fi

# 7. Flag errors.
out=$("$IT2ND" --listen 127.0.0.1 -t 2>&1)
rc=$?
[ $rc = 1 ] && grep -q "\-\-listen '127.0.0.1': expected HOST:PORT" <<<"$out" && ok "--listen without a port: exit 1, says so" ||
    fail "--listen bad: rc $rc: $out"
out=$("$IT2ND" --listen "127.0.0.1:$P1" --metrics "127.0.0.1:$P1" -t 2>&1)
rc=$?
[ $rc = 1 ] && grep -q "the metrics endpoint and a Modbus listener on one address" <<<"$out" &&
    ok "--metrics on the Modbus address refused" || fail "--metrics = --listen: rc $rc: $out"

# 8. Config typos.
printf '[daemon]\nfsync = yes\nstat_dir = ./x\n' > "$T/t1.conf"
out=$("$IT2ND" -c "$T/t1.conf" -t 2>&1)
[ $? = 1 ] && grep -q "t1.conf:3: \[daemon\] stat_dir: unknown key: did you mean 'state_dir'?" <<<"$out" &&
    ok "a misspelt key: did you mean" || fail "typo: $out"
printf '[daemon]\nstate_dir ./x\n' > "$T/t2.conf"
out=$("$IT2ND" -c "$T/t2.conf" -t 2>&1)
[ $? = 1 ] && grep -q "t2.conf:2: \[daemon\] 'state_dir ./x': no '=' in this line: expected key = value (state_dir = ...?)" <<<"$out" &&
    ok "a line without '=': named as such" || fail "no '=': $out"
printf '[rtu:bus]\ndevice = /dev/null\nparity = evn\n' > "$T/t3.conf"
out=$("$IT2ND" -c "$T/t3.conf" -t 2>&1)
[ $? = 1 ] && grep -q "t3.conf:3: \[rtu:bus\] parity: expected none, even or odd: did you mean 'even'?" <<<"$out" &&
    ok "a misspelt value: did you mean" || fail "value typo: $out"

# 8b. --config-keys prints the schema: every section, a key with its range
# and default, and exits 0; an unknown format is a usage error (exit 2).
out=$("$IT2ND" --config-keys 2>&1); rc=$?
secs=$(grep -cE '^\[(daemon|modbus|listen:NAME|rtu:NAME|model:ID|link:NAME|sparkplug|metrics)\]' <<<"$out")
[ $rc = 0 ] && [ "$secs" = 8 ] && grep -q "^  max_clients = 1..512  (default: 32)" <<<"$out" &&
    ok "--config-keys: 8 sections, ranges and defaults" || fail "--config-keys: rc $rc, $secs sections: $out"
out=$("$IT2ND" --config-keys=markdown 2>&1); rc=$?
[ $rc = 0 ] && grep -q '^| `keepalive` | 5..3600 s | `30` | restart |' <<<"$out" &&
    ok "--config-keys=markdown: the docs' tables" || fail "--config-keys=markdown: rc $rc: $out"
out=$("$IT2ND" --config-keys=yaml 2>&1); rc=$?
[ $rc = 2 ] && grep -q "expected text, markdown or dict" <<<"$out" && ok "--config-keys=yaml: exit 2, says what is known" ||
    fail "--config-keys=yaml: rc $rc: $out"

# 9. make run PORT= STATE= METRICS= passes the flags.
out=$(make -s -n -C "$ROOT" run PORT=15020 STATE=./state2 METRICS=127.0.0.1:9102 2>&1 | grep "exec ")
grep -q -- "--listen 127.0.0.1:15020 --state-dir ./state2 --metrics 127.0.0.1:9102" <<<"$out" &&
    ok "make run PORT=15020 STATE=./state2 METRICS=...: $out" || fail "make run flags: $out"

tl_finish
