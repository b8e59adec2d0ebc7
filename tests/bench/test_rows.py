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
bench directory holding them. Then the confidence intervals of ratios from
interleaved rounds: their coverage on simulated noise, the stopping rule,
and that a target counts as met only when the whole interval meets it.
"""
import json
import os
import random
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "mcu"))
from results import precise, ratio_interval, row, validate  # noqa: E402

sys.path.insert(0, os.path.join(HERE, "..", "lib"))
from it2ntest import report  # noqa: E402

R = report.Report("bench-rows", quiet_ok=True)  # thousands of checks: failures only
check = R.check
fails = R.fails


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

# Intervals: a 95 % interval from paired rounds holds the true ratio about
# 95 % of the time (lognormal noise of 8 % per side, 6 rounds).
TRUE = 0.97
hits, trials = 0, 2000
for _ in range(trials):
    a = [100 * TRUE * rng.lognormvariate(0, 0.08) for _ in range(6)]
    b = [100 * rng.lognormvariate(0, 0.08) for _ in range(6)]
    v, bl, lo, hi = ratio_interval(a, b)
    hits += lo <= TRUE <= hi
    check(lo <= v / bl <= hi, "the ratio outside its own interval")
check(0.92 <= hits / trials <= 0.98, f"interval coverage {hits / trials:.3f}, want about 0.95")
# precise(): within +-5 % once the noise is small enough, never from 2 rounds.
quiet = [100 * rng.lognormvariate(0, 0.01) for _ in range(5)]
check(precise(quiet, [100.0] * 5) and not precise(quiet[:2], [100.0] * 2), "precise() on quiet rounds")
check(not precise([100, 140, 70, 120, 90], [100] * 5), "precise() on rounds spread +-40 %")
# A target is met only when the whole interval meets it.
r = row("tp", "req/s", 101.0, 100.0, 1.0, sense=">=", interval=(0.97, 1.05), rounds=6)
check(r["ratio"] == 1.01 and r["met"] is False and validate([r]) == [], f"straddling interval: {r}")
r = row("tp", "req/s", 104.0, 100.0, 1.0, sense=">=", interval=(1.01, 1.07), rounds=6)
check(r["met"] is True and validate([r]) == [], f"interval above the target: {r}")
r = row("cpu", "us", 9.0, 10.0, 1.0, interval=(0.85, 1.02), rounds=9)
check(r["met"] is False and validate([r]) == [], f"upper bound straddling: {r}")
forged = dict(r, met=True)
check(any("met inconsistent" in x for x in validate([forged])), "a met straddling interval not refused")
check(any("does not hold" in x for x in validate([dict(r, interval=[0.95, 0.99])])),
      "an interval not holding its ratio not refused")

print(f"bench rows: {len(rows)} random rows accepted, {caught} built the old way refused, "
      f"interval coverage {hits / trials:.3f}")
sys.exit(R.finish())
