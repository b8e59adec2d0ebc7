#!/bin/bash
# End to end: the instrument firmware (examples/firmware/) on qemu
# mps2-an385 with UART0 on a pty, served by a real it2nd as [link:fw];
# after the upload is committed, pymodbus reads the results over loopback
# Modbus TCP and they must be bit-identical to the firmware's own
# evaluations (printed over semihosting). Run 1: direct pty. Run 2 (unless
# FW_LOSSY=0): a relay between qemu and the daemon drops bytes. Writes
# bench/firmware.json (sizes from the map, upload times).
# FW_ROUNDS=N (make bench-firmware): more rounds of a direct and a lossy run
# back to back (order alternating, a new drop seed per round) until the
# upload ratio's 95 % interval lies within +-5 % (at least 3, at most N
# rounds; tests/bench/mcu/results.py), stored as a ratio row with its interval.
# Env: IT2ND, FW_ELF, FW_MAP; FW_TIMEOUT (s, default 120).
set -u
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
. "$ROOT/tests/lib/testlib.sh"
tl_init fw-e2e it2n-fw
TL_KEEP=${FW_KEEP:-}
QPID='' DPID='' RPID=''
LIMIT=${FW_TIMEOUT:-120}

stop_pids() {
    local p
    for p in $QPID $DPID $RPID; do
        kill "$p" 2>/dev/null && wait "$p" 2>/dev/null
    done
    QPID='' DPID='' RPID=''
}
tl_on_exit() { stop_pids; }

# run NAME DROP_PPM [SEED] (bytes dropped per million, each direction; the
# relay's seed, default 7): one firmware run against a fresh daemon.
run() {
    local name=$1 drop=$2 seed=${3:-7} d=$T/$1 port pty dev
    mkdir -p "$d/state"
    port=$(free_port)
    qemu-system-arm -M mps2-an385 -display none -S \
        -monitor "unix:$d/mon.sock,server=on,wait=off" -serial pty \
        -semihosting-config enable=on,target=native -kernel "$FW_ELF" \
        </dev/null >"$d/qemu.log" 2>&1 &
    QPID=$!
    for _ in $(seq 100); do
        pty=$(sed -n 's/.*char device redirected to \(\/dev\/pts\/[0-9]*\).*/\1/p' "$d/qemu.log")
        [ -n "$pty" ] && [ -S "$d/mon.sock" ] && break
        sleep 0.05
    done
    [ -n "$pty" ] || { fail "$name: qemu gave no pty"; cat "$d/qemu.log" >&2; stop_pids; return; }
    dev=$pty
    if [ "$drop" != 0 ]; then
        python3 "$ROOT/tests/firmware/lossy_relay.py" "$pty" "$d/relay.pty" "$drop" "$seed" \
            >"$d/relay.log" 2>&1 &
        RPID=$!
        for _ in $(seq 100); do [ -s "$d/relay.pty" ] && break; sleep 0.05; done
        dev=$(cat "$d/relay.pty")
        [ -n "$dev" ] || { fail "$name: relay did not start"; stop_pids; return; }
    fi
    printf '[daemon]\nstate_dir = %s\nlink_backoff_max = 1\n[modbus]\ntcp_listen = 127.0.0.1:%s\n' \
        "$d/state" "$port" > "$d/it2nd.conf"
    printf '[model:1]\nunit_id = 1\nn = 3\nm = 3\n[link:fw]\ntype = serial\ndevice = %s\nbaud = 115200\n' \
        "$dev" >> "$d/it2nd.conf"
    "$IT2ND" -c "$d/it2nd.conf" -f -v >"$d/daemon.log" 2>&1 &
    DPID=$!
    wait_port "$port" "$DPID"
    kill -0 "$DPID" 2>/dev/null || { fail "$name: it2nd did not start"; cat "$d/daemon.log" >&2; stop_pids; return; }
    sleep 0.2
    python3 "$ROOT/tests/firmware/qemu_cont.py" "$d/mon.sock" \
        || { fail "$name: qemu monitor: cont not confirmed"; stop_pids; return; }
    local t=0 rc
    while kill -0 "$QPID" 2>/dev/null && [ $t -lt $((LIMIT * 10)) ]; do sleep 0.1; t=$((t + 1)); done
    if kill -0 "$QPID" 2>/dev/null; then
        fail "$name: firmware did not finish within ${LIMIT}s"; cat "$d/qemu.log" >&2; stop_pids; return
    fi
    wait "$QPID"; rc=$?; QPID=
    if [ $rc -ne 0 ] || ! grep -q '^PASS firmware' "$d/qemu.log" || grep -q '^FAIL' "$d/qemu.log"; then
        fail "$name: firmware exit status $rc"; cat "$d/qemu.log" >&2; stop_pids; return
    fi
    grep -E '^(UPLOAD|QUERY|STACK)' "$d/qemu.log"
    ok "$name: upload committed, every QUERY_RESULT bit-identical to the firmware's evaluation"
    if /usr/bin/python3 "$ROOT/tests/firmware/fw_check.py" "$port" "$d/qemu.log" 1; then
        ok "$name: Modbus float32 results bit-identical to the firmware's own evaluations"
    else
        fail "$name: Modbus results differ"
    fi
    stop_pids
}

# upload_ms of round K's runs (1: direct, lossy; K: direct-K, lossy-K)
# paired by round; exit 0 once the lossy/direct interval is within +-5 %.
precise() {
    /usr/bin/python3 - "$T" "$ROOT" <<'PY'
import os, re, sys
sys.path.insert(0, os.path.join(sys.argv[2], "tests", "bench", "mcu"))
from results import precise
t, ms = sys.argv[1], {}
for k in range(1, 1000):
    for side in ("direct", "lossy"):
        log = os.path.join(t, side if k == 1 else "%s-%d" % (side, k), "qemu.log")
        m = re.search(r"^UPLOAD committed ms (\d+)", open(log).read(), re.M) if os.path.exists(log) else None
        if m:
            ms.setdefault(side, {})[k] = int(m.group(1))
ks = sorted(set(ms.get("direct", {})) & set(ms.get("lossy", {})))
sys.exit(0 if precise([ms["lossy"][k] for k in ks], [ms["direct"][k] for k in ks]) else 1)
PY
}

run direct 0
[ "${FW_LOSSY:-1}" != 0 ] && run lossy 500
k=2
while [ "$FAILS" = 0 ] && [ "${FW_LOSSY:-1}" != 0 ] && [ "$k" -le "${FW_ROUNDS:-1}" ]; do
    [ "$k" -gt 3 ] && precise && break
    if [ $((k % 2)) = 0 ]; then
        run "lossy-$k" 500 $((k + 6)); run "direct-$k" 0
    else
        run "direct-$k" 0; run "lossy-$k" 500 $((k + 6))
    fi
    k=$((k + 1))
done

if [ "$FAILS" = 0 ]; then
    FW_OUT=${FW_OUT:-$ROOT/build/firmware.json}
    mkdir -p "$(dirname "$FW_OUT")"
    python3 - "$FW_MAP" "$FW_ELF" "$T" "$FW_OUT" "$ROOT" <<'PY' || fail "figures: sizes, stack bound or high-water check"
import glob, json, re, subprocess, sys, os
mp, elf, t, out, root = sys.argv[1:6]
sizes = json.loads(subprocess.run([sys.executable, os.path.join(os.path.dirname(out), "..",
                   "tests", "firmware", "fw_sizes.py"), mp], check=True, capture_output=True, text=True).stdout)
bsd = subprocess.run(["arm-none-eabi-size", "-A", elf], check=True, capture_output=True, text=True).stdout
sec = {l.split()[0]: int(l.split()[1]) for l in bsd.splitlines() if l.startswith(".")}
sys.path.insert(0, os.path.join(root, "tests", "bench", "mcu"))
from results import ratio_interval, row
def upload(name, drop, seed):
    log = os.path.join(t, name, "qemu.log")
    if not os.path.exists(log):
        return None
    m = re.search(r"^UPLOAD committed ms (\d+) puts (\d+) entries (\d+) retx (\d+)", open(log).read(), re.M)
    st = re.search(r"^STACK high-water bytes (\d+)", open(log).read(), re.M)
    if not m:
        return None
    return {"stack_high_water_bytes": int(st.group(1)) if st else None, "byte_drop_ppm": drop,
            "upload_ms": int(m.group(1)), "put_frames": int(m.group(2)),
            "entries": int(m.group(3)), "retransmissions": int(m.group(4)), "relay_seed": seed if drop else None}
# round 1: "direct" and "lossy" (the figures in docs/firmware-emulated.md);
# round k >= 2 (FW_ROUNDS): "direct-k" and "lossy-k", the relay seeded k + 6
runs, rounds = {}, []
for k in range(1, 1000):
    d = upload("direct" if k == 1 else "direct-%d" % k, 0, None)
    l = upload("lossy" if k == 1 else "lossy-%d" % k, 500, 7 if k == 1 else k + 6)
    if k == 1:
        runs.update({n: r for n, r in (("direct", d), ("lossy", l)) if r})
    if not (d and l):
        break
    rounds.append({"direct": d, "lossy": l})
res = {"target": "qemu mps2-an385, Cortex-M3, arm-none-eabi-gcc -Os",
       "image": {"flash_bytes": sec.get(".text", 0) + sec.get(".ARM.exidx", 0) + sec.get(".data", 0),
                 "static_ram_bytes": sec.get(".data", 0) + sec.get(".bss", 0),
                 "stack_reserved_bytes": sec.get(".stack", 0)},
       "parts_from_map": sizes["parts"],
       "upload_over_emulated_uart": runs,
       "upload_rounds": rounds,
       "loadavg": os.getloadavg(), "cpus": os.cpu_count(),
       "note": "upload_ms is SysTick time from the first HELLO to the COMMIT's ACK over a qemu pty (no baud-rate "
               "pacing): it follows the host's load; upload_rounds: a direct and a lossy run back to back, the "
               "order alternating, a new drop seed per round, until the ratio's 95 % interval lies within +-5 % "
               "or FW_ROUNDS rounds ran"}
cis = sorted(glob.glob(os.path.join(os.path.dirname(elf), "**", "*.ci"), recursive=True))
st = json.loads(subprocess.run([sys.executable, os.path.join(root, "tests", "firmware", "fw_stack.py"), elf] + cis,
                               check=True, capture_output=True, text=True).stdout)
res["stack"] = {"worst_case_bytes": st["worst_case_bytes"], "method": st["method"],
                "main_bytes": st["main_bytes"], "interrupt_bytes": st["interrupt_bytes"],
                "deepest_chain": st["main_chain"]}
hw = [r["stack_high_water_bytes"] for rd in rounds for r in rd.values() if r.get("stack_high_water_bytes")]
hw += [r["stack_high_water_bytes"] for r in runs.values() if r.get("stack_high_water_bytes")]
if hw and max(hw) > st["worst_case_bytes"]:
    sys.exit("fw-e2e: measured stack high-water %d above the static worst case %d: the analysis misses a path"
             % (max(hw), st["worst_case_bytes"]))
def info(name, unit, value):
    return row(name, unit, value)
P = res["parts_from_map"]
rows = [info("firmware image flash (qemu mps2-an385, Cortex-M3, -Os)", "bytes", res["image"]["flash_bytes"]),
        info("firmware image static RAM (data+bss)", "bytes", res["image"]["static_ram_bytes"])]
for part in ("core", "protocol", "driver", "application"):
    if part in P:
        rows.append(info("firmware flash: %s" % part, "bytes", P[part]["flash"]))
        rows.append(info("firmware static RAM: %s" % part, "bytes", P[part]["ram"]))
rows.append(info("firmware worst-case stack (static call-graph bound)", "bytes", st["worst_case_bytes"]))
if hw:
    # the deepest of all runs; at most the bound of the row above (checked)
    rows.append(info("firmware stack high-water (painted, measured)", "bytes", max(hw)))
if "direct" in runs:
    rows.append(info("firmware upload over the emulated UART (HELLO..COMMIT ACK)", "ms", runs["direct"]["upload_ms"]))
if len(rounds) >= 2:  # a time ratio only from interleaved rounds, with its interval
    v, b, lo, hi = ratio_interval([r["lossy"]["upload_ms"] for r in rounds], [r["direct"]["upload_ms"] for r in rounds])
    rows.append(row("firmware upload, 500 ppm byte drop vs direct", "ms", round(v, 1), round(b, 1),
                    interval=[lo, hi], rounds=len(rounds)))
res["rows"] = rows
json.dump(res, open(out, "w"), indent=2, sort_keys=True)
open(out, "a").write("\n")
PY
    [ "$FAILS" = 0 ] && echo "fw-e2e: figures in $FW_OUT"
fi
tl_finish
