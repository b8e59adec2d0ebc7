#!/usr/bin/python3
"""Regression test (issue 22): every row a benchmark stores passes the
collector's own consistency checks, whatever the digits.

bench/fc23.json once stored value 11.27 and baseline 8.78 (rounded to two
decimals) beside a ratio 1.285 taken before rounding; collect.py refused it
(ratio != value/baseline beyond 1e-3) and `make bench` failed on its own
rounding. Rows are now built by one function, results.row(), from the stored
values. This test feeds the collector such figures, built the old way (must
be refused: the check itself can fail) and the new way (must be accepted),
over many random magnitudes and digit counts, and runs collect.py on a
bench directory holding them.
"""
import json
import os
import random
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "mcu"))
from results import row, validate  # noqa: E402

fails = []


def check(cond, what):
    if not cond:
        fails.append(what)


def old_row(name, value, baseline, digits):
    """The fc23 writer before the fix: ratio from the unrounded figures."""
    return {"name": name, "unit": "us", "value": round(value, digits), "baseline": round(baseline, digits),
            "ratio": round(value / baseline, 3), "target": None, "met": None}


# The figures of the failing run (issue 22): 11.2749 vs 8.7751 us.
bad = validate([old_row("fc23 cpu", 11.2749, 8.7751, 2)])
check(bad and "ratio != value/baseline" in bad[0], f"the old rounding is not caught: {bad}")
good = row("fc23 cpu", "us", round(11.2749, 2), round(8.7751, 2))
check(validate([good]) == [], f"the issue's figures, stored by row(): {validate([good])}")

rng = random.Random(22)
rows, caught = [], 0
for i in range(5000):
    mag = 10 ** rng.uniform(-2, 5)
    v, b = mag * rng.uniform(0.5, 2.0), mag * rng.uniform(0.5, 2.0)
    d = rng.choice([0, 1, 2, 3])
    sense = rng.choice(["<=", ">="])
    t = rng.choice([None, 1.0, 0.75])
    r = row(f"r{i}", "x", round(v, d) if d else round(v), round(b, d) if d else round(b), t, sense=sense)
    if r["baseline"]:
        rows.append(r)
    caught += bool(validate([old_row(f"o{i}", v, b, d)]))
probs = validate(rows)
check(probs == [], f"{len(probs)} of {len(rows)} rows built by row() refused, first: {probs[:3]}")
check(caught > 0, "no row built the old way was refused: the check cannot fail")

# The collector end to end, on a bench directory of such rows.
with tempfile.TemporaryDirectory(prefix="it2n-rows.") as d:
    with open(os.path.join(d, "fc23.json"), "w", encoding="utf-8") as f:
        json.dump({"rows": rows[:200] + [good]}, f)
    p = subprocess.run([sys.executable, os.path.join(HERE, "collect.py"), d], capture_output=True, text=True)
    check(p.returncode == 0, f"collect.py refused rows built by row(): {p.stderr[-500:]}")
    with open(os.path.join(d, "fc23.json"), "w", encoding="utf-8") as f:
        json.dump({"rows": [old_row("fc23 cpu", 11.2749, 8.7751, 2)]}, f)
    p = subprocess.run([sys.executable, os.path.join(HERE, "collect.py"), d], capture_output=True, text=True)
    check(p.returncode != 0 and "ratio != value/baseline" in p.stderr, "collect.py accepted the old rounding")

print(f"bench rows: {len(rows)} random rows accepted, {caught} built the old way refused")
for f in fails:
    print("FAIL:", f)
print(f"{2 + 3 - len(fails)} passed, {len(fails)} failed")
sys.exit(1 if fails else 0)
