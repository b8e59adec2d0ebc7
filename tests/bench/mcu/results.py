#!/usr/bin/python3
"""Collect the benchmark's logs into bench/mcu.json (issue 7's figures; merged into bench/results.json by tests/bench/collect.py).

usage: results.py [--smoke] --mode MODE --m0p LOG --m4f LOG --host LOG [LOG...]
                  --flash-map MAP --out JSON

Every LOG holds "R key value..." lines (images, bench_host, sizes.txt, the
callgrind totals). The JSON is an object: "rows", an array of objects
  {name, unit, value, baseline, ratio, target, met[, interval, rounds,
  max_rounds_reached, deterministic]}, and the x86-64 rounds' conditions
("x86_rounds", "x86_loadavg", "cpus"):
- a ratio target: baseline is the compared figure, ratio = value/baseline,
  met = ratio <= target;
- a limit: baseline and ratio are null, met = value <= target;
- information: target and met are null.

Checks (always; --smoke runs only these and the figures its logs allow):
the instruction counter within 1 % in both images, both images report PASS,
the baselines agree with it2n (double within 1e-6, float within 1e-4,
coordinates relative to 1 + max|coordinate|), it2n's results bit-identical on
M0+, M4F and x86-64, and the JSON well-formed. No time or ratio is asserted.
Exit 1 with the reasons on failure.
"""
import argparse
import json
import math
import os
import re
import statistics
import sys

SETS = [("paper4", "paper 4×4"), ("smooth7", "smooth 7×7")]
TARGETS = [("m0p", "M0+"), ("m4f", "M4F")]
IMPLS = ["it2n", "float", "double"]
KEYS = ["name", "unit", "value", "baseline", "ratio", "target", "met"]


def read_log(path, into, passed=None):
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    for line in text.splitlines():
        if line.startswith("R "):
            parts = line.split()
            vals = [float(v) if re.search(r"[.eE]", v) else int(v) for v in parts[2:]]
            into[parts[1]] = vals if len(vals) > 1 else vals[0]
    if passed is not None:
        passed.append(bool(re.search(r"^PASS", text, re.M)) and not re.search(r"^FAIL", text, re.M))


def flash_from_map(path):
    """Bytes of .text*/.rodata* input sections from firmware_core objects kept
    in the link, and of every .text*/.rodata* input section."""
    core = total = 0
    started = False
    pending = None
    full = re.compile(r"^ (\.\S+)\s+0x[0-9a-f]+\s+0x([0-9a-f]+)\s+(\S.*)$")
    cont = re.compile(r"^\s+0x[0-9a-f]+\s+0x([0-9a-f]+)\s+(\S.*)$")
    with open(path, encoding="utf-8") as f:
        for line in f:
            line = line.rstrip("\n")
            if not started:
                started = line.startswith("Linker script and memory map")
                continue
            sec = size = obj = None
            m = full.match(line)
            if m:
                sec, size, obj = m.group(1), int(m.group(2), 16), m.group(3)
            elif pending is not None:
                m = cont.match(line)
                if m:
                    sec, size, obj = pending, int(m.group(1), 16), m.group(2)
            pending = None
            if sec is None:
                m = re.match(r"^ (\.\S+)$", line)
                if m:
                    pending = m.group(1)
                continue
            if re.match(r"^\.(text|rodata)", sec):
                total += size
                if "/firmware_core/" in obj:
                    core += size
    if not started:
        raise SystemExit(f"results.py: {path}: not a GNU ld map file")
    return core, total


# Optional keys after KEYS, in this order: "sense" (">=" for a lower bound),
# "interval" ([lo, hi], the 95 % confidence interval of the ratio),
# "rounds" (how many interleaved rounds gave it), "max_rounds_reached"
# (true: the rounds stopped at the benchmark's maximum with this interval
# still wider than +-PRECISION), "precision" (a row whose rounds went on
# to a narrower interval than +-PRECISION: that width, e.g. 0.005 for a
# ratio within about 1 % of its target) and "deterministic" (true: the figures are
# counts that do not depend on the machine's load: instructions under
# qemu -icount or callgrind, sizes, stack bytes). A row with a ratio has an
# interval or "deterministic": a ratio of times from one run reads met or
# unmet with the noise (issue 22), validate() refuses it.
OPTIONAL = ["sense", "interval", "rounds", "max_rounds_reached", "precision", "deterministic"]

# Rounds are added until the ratio's 95 % interval lies within +-PRECISION
# of it (or the benchmark's maximum of rounds).
PRECISION = 0.05

# Two-sided 95 % quantiles of Student's t, by degrees of freedom (1..30);
# beyond 30 the normal 1.96 is within 2 %.
T95 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
       2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
       2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042]


def ratio_interval(values, baselines):
    """Paired rounds (values[i] measured beside baselines[i]) -> (value,
    baseline, lo, hi): the geometric means of each side, whose quotient is
    the geometric mean of the per-round ratios, and the 95 % confidence
    interval of that ratio (Student's t on the log ratios). A ratio of
    rates is a ratio of times inverted, and logs make the interval
    symmetric in both. Needs two rounds or more."""
    n = len(values)
    if n < 2 or n != len(baselines):
        raise ValueError("ratio_interval: two or more paired rounds needed")
    logs = [math.log(v / b) for v, b in zip(values, baselines)]
    mean = statistics.fmean(logs)
    half = (T95[n - 2] if n - 1 <= len(T95) else 1.96) * statistics.stdev(logs) / math.sqrt(n)
    gv = math.exp(statistics.fmean(math.log(v) for v in values))
    gb = math.exp(statistics.fmean(math.log(b) for b in baselines))
    return gv, gb, math.exp(mean - half), math.exp(mean + half)


def within(lo, hi, rel=PRECISION):
    """True when the interval [lo, hi] lies within +-rel of its (geometric)
    middle, the ratio of the geometric means."""
    mid = math.sqrt(lo * hi)
    return hi / mid - 1 <= rel and 1 - lo / mid <= rel


def precise(values, baselines, rel=PRECISION):
    """True once the ratio's 95 % interval lies within +-rel of it."""
    if len(values) < 3:
        return False
    _, _, lo, hi = ratio_interval(values, baselines)
    return within(lo, hi, rel)


def until_precise(one_round, pairs, max_rounds, min_rounds=3):
    """Interleaved rounds: one_round(r) for r = 0, 1, ... (it measures both
    sides of every ratio, order alternating with r, and appends to the
    lists pairs() returns as [(values, baselines), ...]) until every pair's
    interval is precise() or max_rounds have run. Returns (rounds,
    max_rounds_reached): reached is true when the rounds stopped at the
    maximum with an interval still too wide."""
    r = 0
    while r < max_rounds:
        if r >= min_rounds and all(precise(v, b) for v, b in pairs()):
            break
        one_round(r)
        r += 1
    return r, not all(precise(v, b) for v, b in pairs())


def row(name, unit, value, baseline=None, target=None, sense="<=", met=None, interval=None, rounds=None,
        max_rounds_reached=None, deterministic=False, precision=PRECISION):
    """One figure as stored: the ratio is computed from the value and
    baseline exactly as given (round them first, if at all), and met from
    that stored ratio, so validate() holds by construction whatever the
    digits (a ratio taken before rounding once failed its own check). With
    an interval, a target is met only when the whole interval meets it.
    A ratio needs an interval (from interleaved rounds: rounds, and whether
    they stopped at their maximum, default: whether the interval is wider
    than +-precision) or deterministic=True (counts, not times)."""
    ratio = None if baseline in (None, 0) else round(value / baseline, 4)
    if interval is not None:
        if max_rounds_reached is None and not deterministic:
            max_rounds_reached = not within(interval[0], interval[1], precision)
        interval = [min(round(interval[0], 4), ratio), max(round(interval[1], 4), ratio)]
    if target is not None:
        got = ratio if baseline is not None else value
        if interval is not None:
            got = interval[0] if sense == ">=" else interval[1]
        met = got is not None and (got >= target if sense == ">=" else got <= target)
    r = {"name": name, "unit": unit, "value": value, "baseline": baseline,
         "ratio": ratio, "target": target, "met": met}
    if sense == ">=":
        r["sense"] = ">="
    if interval is not None:
        r["interval"] = interval
        r["rounds"] = rounds
        if not deterministic:
            r["max_rounds_reached"] = bool(max_rounds_reached)
            if precision != PRECISION:
                r["precision"] = precision
    if deterministic:
        r["deterministic"] = True
    return r


def keys_ok(keys):
    """KEYS in order, then any of OPTIONAL in their order."""
    return keys[:len(KEYS)] == KEYS and keys[len(KEYS):] == [k for k in OPTIONAL if k in keys[len(KEYS):]]


class Table:
    def __init__(self, require_targets):
        self.rows = []
        self.missing = []
        self.require = require_targets

    def add(self, name, unit, value, baseline=None, target=None, limit=None, met=None, interval=None,
            rounds=None):
        if value is None or (target is not None and baseline is None):
            if self.require and (target is not None or limit is not None):
                self.missing.append(name)
            return
        if baseline is None and limit is not None:
            target = limit
        # Instructions (qemu -icount, callgrind) and bytes (maps, sizeof,
        # painted stacks) are the same on every run; times are not.
        self.rows.append(row(name, unit, value, baseline, target, met=met, interval=interval, rounds=rounds,
                             deterministic=unit in ("instructions", "bytes")))


def validate(rows):
    """Schema and internal consistency of the JSON rows; returns problems.
    A row is KEYS in that order, plus optionally "sense": ">=" for a target
    that is a lower bound (throughput); without it the target is an upper
    bound (met when the ratio, or the value without a baseline, is <= it).
    A row with "interval" [lo, hi] (and "rounds") meets its target only
    when the whole interval does. A row with a ratio has an interval or
    "deterministic": true (see OPTIONAL)."""
    bad = []
    names = set()
    for r in rows:
        keys = list(r.keys())
        if not keys_ok(keys):
            bad.append(f"row keys {keys}")
            continue
        sense = r.get("sense", "<=")
        if sense not in ("<=", ">="):
            bad.append(f"{r['name']}: sense {sense!r}")
            continue
        if not isinstance(r["name"], str) or r["name"] in names:
            bad.append(f"name missing or duplicate: {r['name']!r}")
        names.add(r["name"])
        num = (int, float)
        if not isinstance(r["value"], num) or not math.isfinite(r["value"]):
            bad.append(f"{r['name']}: value {r['value']!r}")
        for k in ("baseline", "ratio", "target"):
            if r[k] is not None and (not isinstance(r[k], num) or isinstance(r[k], bool)):
                bad.append(f"{r['name']}: {k} {r[k]!r}")
        if r["met"] is not None and not isinstance(r["met"], bool):
            bad.append(f"{r['name']}: met {r['met']!r}")
        if r["baseline"] == 0 and r["ratio"] is not None:
            bad.append(f"{r['name']}: ratio with a zero baseline")
        elif r["baseline"] is not None and r["ratio"] is not None:
            if abs(r["ratio"] - r["value"] / r["baseline"]) > 1e-3 * max(1.0, abs(r["ratio"])):
                bad.append(f"{r['name']}: ratio != value/baseline")
        iv = r.get("interval")
        det = r.get("deterministic")
        if det is not None and det is not True:
            bad.append(f"{r['name']}: deterministic {det!r} (true or absent)")
        if r["ratio"] is not None and iv is None and det is not True:
            bad.append(f"{r['name']}: a ratio with neither an interval from interleaved rounds "
                       f"(results.until_precise) nor \"deterministic\": true")
        cap = r.get("max_rounds_reached")
        if cap is not None and (not isinstance(cap, bool) or iv is None):
            bad.append(f"{r['name']}: max_rounds_reached {cap!r} (a bool, beside an interval)")
        if iv is not None:
            if (not isinstance(iv, list) or len(iv) != 2 or r["ratio"] is None
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in iv)
                    or not iv[0] <= r["ratio"] <= iv[1]):
                bad.append(f"{r['name']}: interval {iv!r} does not hold ratio {r['ratio']!r}")
                continue
            if not isinstance(r.get("rounds"), int) or r["rounds"] < 2:
                bad.append(f"{r['name']}: rounds {r.get('rounds')!r}")
            # Rounds stop early only once the interval is within
            # +-precision (slack: the stored bounds are rounded to 4 digits).
            prec = r.get("precision", PRECISION)
            if "precision" in r and (not isinstance(prec, float) or not 0 < prec < PRECISION
                                     or cap is None or det is True):
                bad.append(f"{r['name']}: precision {prec!r} (below {PRECISION}, beside max_rounds_reached)")
                prec = PRECISION
            slack = 2e-3 if prec == PRECISION else prec / 50
            if cap is False and not within(iv[0], iv[1], prec + slack):
                bad.append(f"{r['name']}: interval {iv!r} wider than +-{prec:.1%} but "
                           f"max_rounds_reached false")
            if cap is True and within(iv[0], iv[1], prec - slack):
                bad.append(f"{r['name']}: interval {iv!r} within +-{prec:.1%} but "
                           f"max_rounds_reached true")
        if r["target"] is not None:
            got = r["ratio"] if r["baseline"] is not None else r["value"]
            if iv is not None:
                got = iv[0] if sense == ">=" else iv[1]
            ok = got is not None and (got >= r["target"] if sense == ">=" else got <= r["target"])
            if r["met"] is not ok:
                bad.append(f"{r['name']}: met inconsistent with target ({sense} {r['target']})")
    return bad


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--smoke", action="store_true")
    ap.add_argument("--mode", default="full")
    ap.add_argument("--m0p", required=True)
    ap.add_argument("--m4f", required=True)
    ap.add_argument("--host", nargs="+", required=True)
    ap.add_argument("--flash-map", required=True)
    ap.add_argument("--flash-map-uniform", required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()

    img = {"m0p": {}, "m4f": {}}
    host = {}
    passed = []
    read_log(a.m0p, img["m0p"], passed)
    read_log(a.m4f, img["m4f"], passed)
    for p in a.host:
        read_log(p, host)
    problems = []
    if not all(passed):
        problems.append("an image did not report PASS")

    t = Table(not a.smoke)
    # ---- the instruction counter -------------------------------------------
    for tg, tname in TARGETS:
        d = img[tg]
        exp, got = d.get("counter.expected"), d.get("counter.measured")
        if not exp or got is None or abs(got - exp) > 0.01 * exp:
            problems.append(f"{tname}: instruction counter off by more than 1 % ({got} vs {exp})")
        t.add(f"{tname} counter check: instructions measured on a loop of known length (baseline: expected)",
              "instructions", got, exp)

    def from_call(tg, key, only=None):
        """How a stack figure was measured (stack_probe.h)."""
        ex = [img[tg].get(f"{s}.{key}_exact") for s, _ in SETS if only in (None, s)]
        return "from the call" if all(e == 1 for e in ex) else "from the measuring thunk's call"

    def med(tg, key):
        v = img[tg].get(key)
        if v is None:
            return None
        v = v if isinstance(v, list) else [v]
        return statistics.median(v)

    # ---- targets first -------------------------------------------------------
    for s, sname in SETS:
        t.add(f"M0+ one full query, {sname}: it2n vs float (median instructions)", "instructions",
              med("m0p", f"{s}.it2n.query"), med("m0p", f"{s}.float.query"), target=0.5)
    for s, sname in SETS:
        t.add(f"M0+ solve, {sname}: it2n vs float", "instructions",
              img["m0p"].get(f"{s}.it2n.solve"), img["m0p"].get(f"{s}.float.solve"), target=1.0)
    for fn, key, lim in (("it2n_eval", "eval_stack", 512), ("it2n_model_solve", "solve_stack", 2048)):
        stacks = [img["m0p"].get(f"{s}.it2n.{key}") for s, _ in SETS]
        t.add(f"M0+ {fn} stack, {from_call('m0p', 'it2n.' + key)} (worst of both data sets)", "bytes",
              None if None in stacks else max(stacks), limit=lim)
    for s, sname in SETS:
        t.add(f"M4F one full query, {sname}: it2n vs float on the FPU (median instructions)", "instructions",
              med("m4f", f"{s}.it2n.query"), med("m4f", f"{s}.float.query"), target=2.0)
    def x86(s, impl):
        """Geometric mean of the interleaved rounds' times (host_rounds.py)."""
        v = host.get(f"{s}.x86.{impl}_ns")
        if v is None:
            return None
        v = v if isinstance(v, list) else [v]
        return round(math.exp(statistics.fmean(math.log(x) for x in v)), 3)

    for s, sname in SETS:
        it, dbl = host.get(f"{s}.x86.it2n_ns"), host.get(f"{s}.x86.double_ns")
        iv = None
        if isinstance(it, list) and isinstance(dbl, list) and len(it) == len(dbl) >= 2:
            _, _, lo, hi = ratio_interval(it, dbl)
            iv = [lo, hi]
        elif it is not None and not a.smoke:
            problems.append(f"{sname}: x86-64 times from fewer than 2 rounds (host_rounds.py)")
        t.add(f"x86-64 one full query, {sname}: it2n vs double (time, interleaved rounds)", "ns",
              x86(s, "it2n"), x86(s, "double"), target=2.0, interval=iv, rounds=host.get("x86.rounds"))
        cg_i, cg_d, npts = host.get(f"{s}.cg.it2n"), host.get(f"{s}.cg.double"), host.get("host.points")
        t.add(f"x86-64 one full query, {sname}: it2n vs double (callgrind instructions, mean of {npts} points)",
              "instructions", None if None in (cg_i, npts) else cg_i / npts,
              None if None in (cg_d, npts) else cg_d / npts, target=2.0)
    for c, lim, cname in (("d3", 6144, "IT2N_MAX_DEGREE=3"), ("d7", 24576, "IT2N_MAX_DEGREE=7 (default)")):
        mo, ds = host.get(f"sizes.{c}.model"), host.get(f"sizes.{c}.dataset")
        if mo is not None and ds is not None:
            t.add(f"RAM: sizeof(it2n_model) + sizeof(it2n_dataset), {cname}", "bytes", mo + ds, limit=lim)
    core, total = flash_from_map(a.flash_map)
    t.add("M0+ core flash (text+rodata) of solve + eval + locate, IT2N_MAX_DEGREE=3", "bytes", core, limit=12288)
    core_u, _ = flash_from_map(a.flash_map_uniform)
    t.add("M0+ core flash (text+rodata) of solve + eval + locate, IT2N_MAX_DEGREE=3, "
          "IT2N_CHORD=0 (uniform parameters only)", "bytes", core_u, limit=12288)
    for s, sname in SETS:
        deg = 3 if s == "paper4" else 7
        maxc = host.get(f"{s}.max_abs_coord")
        t.add(f"accuracy, {sname}: it2n eval worst error, memberships (vs long-double reference)", "abs",
              host.get(f"{s}.it2n.err_memb"), limit=2e-5 if deg <= 3 else 1e-4)
        if maxc is not None:
            t.add(f"accuracy, {sname}: it2n eval worst error, coordinates (max |c| = {maxc:g})", "abs",
                  host.get(f"{s}.it2n.err_coord"),
                  limit=float(f"{(1e-4 + (1e-5 if deg <= 3 else 1e-4) * maxc):.6g}"))
        t.add(f"accuracy, {sname}: it2n control nets vs the exact solution of its Q24 data, "
              f"worst error / (1e-6·max|P| + 1e-7) per channel",
              "of allowed", host.get(f"{s}.it2n.ctrl_goal_ratio"), limit=1.0)

    # ---- bit identity ---------------------------------------------------------
    for s, sname in SETS:
        hs = [img["m0p"].get(f"{s}.it2n.hash"), img["m4f"].get(f"{s}.it2n.hash"), host.get(f"{s}.it2n.hash")]
        same = None not in hs and len(set(hs)) == 1
        if not same:
            problems.append(f"{sname}: it2n results differ between M0+, M4F and x86-64: {hs}")
        t.add(f"it2n results bit-identical on M0+ -Os, M4F -O2, x86-64 -O2, {sname} (1 = yes)", "bool",
              1 if same else 0, met=same)

    # ---- the baselines agree with it2n ---------------------------------------
    for s, sname in SETS:
        maxc = host.get(f"{s}.max_abs_coord", 0.0)
        for impl, tol in (("float", 1e-4), ("double", 1e-6)):
            for src, data, scale in (("M0+", img["m0p"], 1e-9), ("M4F", img["m4f"], 1e-9), ("x86-64", host, 1.0)):
                key = "dev_memb_e9" if scale != 1.0 else "dev_memb"
                dm = data.get(f"{s}.{impl}.{key}")
                dc = data.get(f"{s}.{impl}.{key.replace('memb', 'coord')}")
                if dm is None or dc is None:
                    problems.append(f"{sname}: {src}: no {impl} deviation reported")
                    continue
                dm, dc = dm * scale, dc * scale
                if dm > tol or dc > tol * (1 + maxc):
                    problems.append(f"{sname}: {src}: {impl} baseline disagrees with it2n ({dm:.3g}, {dc:.3g})")

    # ---- information: every count ----------------------------------------------
    for tg, tname in TARGETS:
        t.add(f"{tname} image: query repetitions per timer reading", "calls", img[tg].get("reps"))
    for tg, tname in TARGETS:
        for s, sname in SETS:
            for impl in IMPLS:
                v = img[tg].get(f"{s}.{impl}.query")
                if v is None:
                    continue
                v = v if isinstance(v, list) else [v]
                for stat, f in (("min", min), ("median", statistics.median), ("max", max)):
                    t.add(f"{tname} one full query, {sname}, {impl}: {stat} over {len(v)} points", "instructions", f(v))
            for impl in IMPLS:
                t.add(f"{tname} solve, {sname}, {impl}", "instructions", img[tg].get(f"{s}.{impl}.solve"))
        for s, sname in SETS:
            t.add(f"{tname} one full query, {sname}: it2n vs double (median instructions)", "instructions",
                  med(tg, f"{s}.it2n.query"), med(tg, f"{s}.double.query"))
            t.add(f"{tname} solve, {sname}: it2n vs double", "instructions",
                  img[tg].get(f"{s}.it2n.solve"), img[tg].get(f"{s}.double.solve"))
    for s, sname in SETS:
        t.add(f"M4F solve, {sname}: it2n vs float on the FPU", "instructions",
              img["m4f"].get(f"{s}.it2n.solve"), img["m4f"].get(f"{s}.float.solve"))
    for s, sname in SETS:
        for what, key in (("eval", "eval_stack"), ("solve", "solve_stack")):
            for impl in IMPLS:
                t.add(f"M0+ {impl} {what} stack, {sname}, {from_call('m0p', impl + '.' + key, s)}", "bytes",
                      img["m0p"].get(f"{s}.{impl}.{key}"))
    for s, sname in SETS:
        for impl in IMPLS:
            t.add(f"x86-64 one full query, {sname}, {impl} (time, geometric mean of the rounds)", "ns",
                  x86(s, impl))
    for c in ("d3", "d7"):
        for st in ("model", "dataset"):
            t.add(f"sizeof(it2n_{st}), IT2N_MAX_DEGREE={c[1]}", "bytes", host.get(f"sizes.{c}.{st}"))
    t.add("M0+ flash of the same link including libgcc helpers and mem*, IT2N_MAX_DEGREE=3", "bytes", total)
    for s, sname in SETS:
        for impl in ("float", "double"):
            for k, kname in (("err_memb", "eval worst error, memberships"), ("err_coord", "eval worst error, coordinates"),
                             ("ctrl_err_memb", "control nets worst error, memberships"),
                             ("ctrl_err_coord", "control nets worst error, coordinates")):
                t.add(f"accuracy, {sname}: {impl} {kname}", "abs", host.get(f"{s}.{impl}.{k}"))
        for k, kname in (("ctrl_err_memb", "control nets worst error vs its Q24 data, memberships"),
                         ("ctrl_err_coord", "control nets worst error vs its Q24 data, coordinates"),
                         ("ctrl_err_memb_vs_decimal", "control nets worst error vs the decimal data, memberships"),
                         ("ctrl_err_coord_vs_decimal", "control nets worst error vs the decimal data, coordinates")):
            t.add(f"accuracy, {sname}: it2n {kname}", "abs", host.get(f"{s}.it2n.{k}"))

    problems += [f"figure missing from the logs: {n}" for n in t.missing]
    problems += validate(t.rows)
    # The x86-64 times follow the machine's load: the load average during
    # their rounds is kept beside the rows (host_rounds.py).
    la = host.get("x86.loadavg")
    doc = {"rows": t.rows, "x86_rounds": host.get("x86.rounds"),
           "x86_loadavg": la if isinstance(la, list) else None, "cpus": os.cpu_count()}
    text = json.dumps(doc, indent=1, ensure_ascii=False) + "\n"
    try:
        json.loads(text)
    except ValueError as e:
        problems.append(f"JSON does not parse back: {e}")
    with open(a.out, "w", encoding="utf-8") as f:
        f.write(text)
    if problems:
        for p in problems:
            print(f"results.py: {p}", file=sys.stderr)
        return 1
    print(f"results.py: {len(t.rows)} figures ({a.mode}), "
          f"{sum(1 for r in t.rows if r['target'] is not None)} with a target, "
          f"{sum(1 for r in t.rows if r['met'] is True and r['target'] is not None)} met -> {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
