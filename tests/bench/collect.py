#!/usr/bin/python3
"""bench/results.json: every benchmark's headline figures in one list.

Each benchmark writes its own bench/<name>.json. Its headline figures are
rows {name, unit, value, baseline, ratio, target, met[, sense, interval,
rounds, max_rounds_reached, deterministic]} (the schema of
tests/bench/mcu/results.py: "sense": ">=" marks a target that is a lower
bound, such as a throughput ratio; a ratio row carries the 95 % interval of
its interleaved rounds, or "deterministic": true for counts that are the
same on every run, else it is refused): the file is either a JSON array of rows
(bench/mcu.json) or an object with a "rows" array (and anything else the
benchmark wants to keep: conditions, raw samples). Two early benchmarks
write no rows; ADAPTERS derives theirs from the figures they do write.

A benchmark whose row misses its target says why in an object
"reasons" {row name: text} next to "rows" (perfdoc.py refuses an unmet
target without a reason). This script merges them, in SOURCES order then alphabetically, adding
"source" (the file's stem) to each row, and writes bench/results.json; with
--check it only compares (make test) and fails if the committed
bench/results.json is not what the committed bench/*.json give.

usage: collect.py [--check] [BENCH_DIR]     (default: bench)
"""
import difflib
import glob
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "mcu"))
from results import KEYS, OPTIONAL, keys_ok, row as mkrow, validate  # noqa: E402

# Files shown first, in this order (the issue-7 core figures lead).
SOURCES = ["mcu"]
OUT = "results.json"


def conn_rows(d):
    """tests/daemon/conn_test.py (issue 8 item 7, 8): lock-out and RTU."""
    rows = []
    for key, what in (("lockout_idle_ms", "idle"),
                      ("lockout_slowloris_reconnecting_ms", "slowloris (reconnecting)")):
        if d.get(key):
            rows.append(mkrow(f"it2nd new client served while max_clients {what} connections are held "
                              "(worst of the runs, connect to first reply)", "ms", max(d[key]),
                              target=1000))
    f = d.get("flood_500")
    if f:
        rows.append(mkrow("it2nd 500 connection attempts beyond max_clients: connected clients' failed polls",
                          "requests", f["client_failures"], target=0))
    r = d.get("rtu_115200_after_foreign_5ms")
    if r:
        rows.append(mkrow("it2nd RTU 115 200 baud: requests 5 ms after a foreign frame left unanswered",
                          "requests", r["rounds"] - r["answered"], target=0))
    return rows


def slowdisk_rows(d):
    """tests/daemon/slowdisk_test.py (issue 8 item 6): reads vs a slow disk."""
    rows = []
    s = d.get("slow_disk")
    if s:
        ms = s["delay_ms"]
        rows.append(mkrow(f"it2nd read-only FC04 median latency, fdatasync delayed {ms} ms", "ms",
                          s["median_ms"], target=2))
        rows.append(mkrow(f"it2nd read-only FC04 p99 latency, fdatasync delayed {ms} ms", "ms",
                          s["p99_ms"], target=20))
    b = d.get("baseline_no_delay")
    if b:
        rows.append(mkrow("it2nd read-only FC04 median latency, no delay", "ms", b["median_ms"]))
    return rows


ADAPTERS = {"daemon_conn": conn_rows, "daemon_slowdisk": slowdisk_rows}


def collect(bench_dir):
    paths = sorted(glob.glob(os.path.join(bench_dir, "*.json")))
    stems = [os.path.splitext(os.path.basename(p))[0] for p in paths]
    order = [s for s in SOURCES if s in stems] + [s for s in stems if s not in SOURCES]
    rows, bad = [], []
    for stem in order:
        if stem + ".json" == OUT:
            continue
        path = os.path.join(bench_dir, stem + ".json")
        try:
            with open(path, encoding="utf-8") as f:
                data = json.load(f)
        except (OSError, ValueError) as e:
            bad.append(f"{path}: {e}")
            continue
        if isinstance(data, list):
            part = data
        elif isinstance(data, dict) and "rows" in data:
            part = data["rows"]
        elif stem in ADAPTERS:
            part = ADAPTERS[stem](data)
        else:
            continue  # raw figures only (e.g. firmware.json before it had rows)
        if not isinstance(part, list):
            bad.append(f"{path}: rows is not a list")
            continue
        # Key order as KEYS (+ OPTIONAL), whatever order the writer used.
        part = [{k: r[k] for k in KEYS + OPTIONAL if k in r} if isinstance(r, dict) and set(r) <= set(KEYS + OPTIONAL)
                else r for r in part]
        bad += [f"{path}: {b}" for b in validate(part)]
        why = data.get("reasons", {}) if isinstance(data, dict) else {}
        for r in part:
            if isinstance(r, dict) and keys_ok(list(r.keys())):
                r = dict(r, source=stem)
                if r["met"] is False and r["name"] in why:
                    r["why"] = why[r["name"]]
                rows.append(r)
    names = [r["name"] for r in rows]
    bad += [f"duplicate row name across files: {n!r}" for n in sorted(set(n for n in names if names.count(n) > 1))]
    return rows, bad


def main():
    args = sys.argv[1:]
    check = bool(args) and args[0] == "--check"
    if check:
        args = args[1:]
    bench_dir = args[0] if args else "bench"
    rows, bad = collect(bench_dir)
    for b in bad:
        print(f"collect.py: {b}", file=sys.stderr)
    if bad:
        return 1
    text = json.dumps(rows, indent=1, ensure_ascii=False) + "\n"
    out = os.path.join(bench_dir, OUT)
    if not check:
        with open(out, "w", encoding="utf-8") as f:
            f.write(text)
        ratios = [r for r in rows if r["ratio"] is not None]
        print(f"collect.py: {out}: {len(rows)} figures from {len(set(r['source'] for r in rows))} benchmarks; "
              f"{len(ratios)} ratios: {sum(1 for r in ratios if r.get('deterministic'))} exact counts "
              f"(deterministic), {sum(1 for r in ratios if not r.get('deterministic'))} from interleaved "
              f"rounds with a 95 % interval "
              f"({sum(1 for r in ratios if r.get('max_rounds_reached'))} at their maximum of rounds)")
        return 0
    try:
        with open(out, encoding="utf-8") as f:
            have = f.read()
    except OSError as e:
        print(f"collect.py: {e}", file=sys.stderr)
        return 1
    if have != text:
        sys.stderr.writelines(difflib.unified_diff(have.splitlines(True), text.splitlines(True), out,
                                                   "collected from " + bench_dir + "/*.json"))
        print(f"collect.py: {out} is not what {bench_dir}/*.json give: run make bench-collect", file=sys.stderr)
        return 1
    print(f"collect.py: {out} matches {bench_dir}/*.json ({len(rows)} figures)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
