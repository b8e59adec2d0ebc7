#!/bin/bash
# End to end: the instrument firmware (examples/firmware/) on qemu
# mps2-an385 with UART0 on a pty, served by a real it2nd as [link:fw];
# after the upload is committed, pymodbus reads the results over loopback
# Modbus TCP and they must be bit-identical to the firmware's own
# evaluations (printed over semihosting). Run 1: direct pty. Run 2 (unless
# FW_LOSSY=0): a relay between qemu and the daemon drops bytes. Writes
# bench/firmware.json (sizes from the map, upload times).
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

# run NAME DROP_PPM (bytes dropped per million, each direction): one firmware run against a fresh daemon.
run() {
    local name=$1 drop=$2 d=$T/$1 port pty dev
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
        python3 "$ROOT/tests/firmware/lossy_relay.py" "$pty" "$d/relay.pty" "$drop" 7 \
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

run direct 0
[ "${FW_LOSSY:-1}" != 0 ] && run lossy 500

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
runs = {}
for name, drop in (("direct", 0), ("lossy", 500)):
    log = os.path.join(t, name, "qemu.log")
    if not os.path.exists(log):
        continue
    m = re.search(r"^UPLOAD committed ms (\d+) puts (\d+) entries (\d+) retx (\d+)", open(log).read(), re.M)
    st = re.search(r"^STACK high-water bytes (\d+)", open(log).read(), re.M)
    if m:
        runs[name] = {"stack_high_water_bytes": int(st.group(1)) if st else None, "byte_drop_ppm": drop, "upload_ms": int(m.group(1)), "put_frames": int(m.group(2)),
                      "entries": int(m.group(3)), "retransmissions": int(m.group(4))}
res = {"target": "qemu mps2-an385, Cortex-M3, arm-none-eabi-gcc -Os",
       "image": {"flash_bytes": sec.get(".text", 0) + sec.get(".ARM.exidx", 0) + sec.get(".data", 0),
                 "static_ram_bytes": sec.get(".data", 0) + sec.get(".bss", 0),
                 "stack_reserved_bytes": sec.get(".stack", 0)},
       "parts_from_map": sizes["parts"],
       "upload_over_emulated_uart": runs,
       "note": "upload_ms is SysTick time from the first HELLO to the COMMIT's ACK over a qemu pty (no baud-rate pacing)"}
cis = sorted(glob.glob(os.path.join(os.path.dirname(elf), "**", "*.ci"), recursive=True))
st = json.loads(subprocess.run([sys.executable, os.path.join(root, "tests", "firmware", "fw_stack.py"), elf] + cis,
                               check=True, capture_output=True, text=True).stdout)
res["stack"] = {"worst_case_bytes": st["worst_case_bytes"], "method": st["method"],
                "main_bytes": st["main_bytes"], "interrupt_bytes": st["interrupt_bytes"],
                "deepest_chain": st["main_chain"]}
hw = [r["stack_high_water_bytes"] for r in runs.values() if r.get("stack_high_water_bytes")]
if hw and max(hw) > st["worst_case_bytes"]:
    sys.exit("fw-e2e: measured stack high-water %d above the static worst case %d: the analysis misses a path"
             % (max(hw), st["worst_case_bytes"]))
def info(name, unit, value, baseline=None):
    return {"name": name, "unit": unit, "value": value, "baseline": baseline,
            "ratio": round(value / baseline, 4) if baseline else None, "target": None, "met": None}
P = res["parts_from_map"]
rows = [info("firmware image flash (qemu mps2-an385, Cortex-M3, -Os)", "bytes", res["image"]["flash_bytes"]),
        info("firmware image static RAM (data+bss)", "bytes", res["image"]["static_ram_bytes"])]
for part in ("core", "protocol", "driver", "application"):
    if part in P:
        rows.append(info("firmware flash: %s" % part, "bytes", P[part]["flash"]))
        rows.append(info("firmware static RAM: %s" % part, "bytes", P[part]["ram"]))
rows.append(info("firmware worst-case stack (static call-graph bound)", "bytes", st["worst_case_bytes"]))
if hw:
    rows.append(info("firmware stack high-water (painted, measured)", "bytes", max(hw), st["worst_case_bytes"]))
if "direct" in runs:
    rows.append(info("firmware upload over the emulated UART (HELLO..COMMIT ACK)", "ms", runs["direct"]["upload_ms"]))
    if "lossy" in runs:
        rows.append(info("firmware upload, 500 ppm byte drop vs direct", "ms", runs["lossy"]["upload_ms"],
                         runs["direct"]["upload_ms"]))
res["rows"] = rows
json.dump(res, open(out, "w"), indent=2, sort_keys=True)
open(out, "a").write("\n")
PY
    [ "$FAILS" = 0 ] && echo "fw-e2e: figures in $FW_OUT"
fi
tl_finish
