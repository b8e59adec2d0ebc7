#!/usr/bin/env python3
"""End-to-end tests of the `it2n` CLI binary.

Runs the binary given as argv[1] (run from the repository root) and checks
exit statuses, stderr messages, output headers, and the numbers against an
independent reference: the Bernstein collocation system solved exactly with
fractions.Fraction (chord-length parameters in double, as the NURBS Book
computes them from footprint D).
"""
import math
import os
import subprocess
import sys
import tempfile
from fractions import Fraction as Fr

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

BIN = sys.argv[1]
FPS = ["LL", "LR", "L", "D", "R", "RL", "RR"]
TOL_MEMB = 2e-5
# thousands of checks: only failures, skips and the summary are printed
R = report.Report("cli-e2e", quiet_ok=True)
check = R.check


def run(*args, stdin=None):
    p = subprocess.run([BIN, *args], capture_output=True, text=True,
                       input=stdin, timeout=60)
    return p.returncode, p.stdout, p.stderr


def rows(out):
    lines = out.strip().split("\n")
    return lines[0], [ln.split(",") for ln in lines[1:]]


# ---- Exact reference ------------------------------------------------------

def load(path):
    """{(i,j,fp): {ch: Fraction}}, has_z"""
    data, hdr = {}, None
    for line in open(path):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        if hdr is None:
            hdr = line.split(",")
            continue
        f = line.split(",")
        data[(int(f[0]), int(f[1]), f[2])] = {
            h: Fr(v) for h, v in zip(hdr[3:], f[3:])}
    return data, "z" in hdr


def bern(n, k, t):
    return math.comb(n, k) * t ** k * (1 - t) ** (n - k)


def dbern(n, k, t):
    lo = bern(n - 1, k - 1, t) if k >= 1 else 0
    hi = bern(n - 1, k, t) if k <= n - 1 else 0
    return n * (lo - hi)


def inverse(a):
    n = len(a)
    m = [row[:] + [Fr(int(i == j)) for j in range(n)] for i, row in enumerate(a)]
    for c in range(n):
        p = next(r for r in range(c, n) if m[r][c] != 0)
        m[c], m[p] = m[p], m[c]
        pv = m[c][c]
        m[c] = [x / pv for x in m[c]]
        for r in range(n):
            if r != c and m[r][c] != 0:
                f = m[r][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return [row[n:] for row in m]


def chord_params(data, n, m, has_z, direction):
    """NURBS Book 9.2.5 from footprint D, averaged over lines (double)."""
    deg, lines = (n, m) if direction == 0 else (m, n)
    acc, used = [0.0] * (deg + 1), 0
    axes = ["x", "y"] + (["z"] if has_z else [])
    for line in range(lines + 1):
        def pt(k):
            key = (k, line, "D") if direction == 0 else (line, k, "D")
            return [float(data[key][a]) for a in axes]
        d = [0.0] + [math.dist(pt(k - 1), pt(k)) for k in range(1, deg + 1)]
        total = sum(d)
        if total == 0:
            continue
        used += 1
        cum = 0.0
        for k in range(1, deg):
            cum += d[k]
            acc[k] += cum / total
    t = [Fr(acc[k] / used) for k in range(deg + 1)]
    t[0], t[deg] = Fr(0), Fr(1)
    return t


class Ref:
    def __init__(self, path, chord=False):
        self.data, self.has_z = load(path)
        self.n = max(k[0] for k in self.data)
        self.m = max(k[1] for k in self.data)
        self.fps = sorted({k[2] for k in self.data}, key=FPS.index)
        self.chs = ["x", "y"] + (["z"] if self.has_z else []) + ["T", "I", "F"]
        n, m = self.n, self.m
        if chord:
            u = chord_params(self.data, n, m, self.has_z, 0)
            w = chord_params(self.data, n, m, self.has_z, 1)
        else:
            u = [Fr(i, n) for i in range(n + 1)]
            w = [Fr(j, m) for j in range(m + 1)]
        ai = inverse([[bern(n, a, u[i]) for a in range(n + 1)]
                      for i in range(n + 1)])
        ci = inverse([[bern(m, b, w[j]) for b in range(m + 1)]
                      for j in range(m + 1)])
        # F = A P C^T  =>  P = A^-1 F C^-T
        self.ctrl = {}
        for fp in self.fps:
            for ch in self.chs:
                f = [[self.data[(i, j, fp)][ch] for j in range(m + 1)]
                     for i in range(n + 1)]
                p = [[sum(ai[a][i] * f[i][j] * ci[b][j]
                          for i in range(n + 1) for j in range(m + 1))
                      for b in range(m + 1)] for a in range(n + 1)]
                self.ctrl[(fp, ch)] = p

    def surf(self, fp, ch, u, w, du=False, dw=False):
        n, m, p = self.n, self.m, self.ctrl[(fp, ch)]
        bu = dbern if du else bern
        bw = dbern if dw else bern
        return sum(bu(n, a, u) * bw(m, b, w) * p[a][b]
                   for a in range(n + 1) for b in range(m + 1))

    def coord_tol(self):
        big = max(abs(v[c]) for v in self.data.values()
                  for c in ("x", "y", "z") if c in v)
        return 1e-4 + 1e-5 * float(big)


def compare_eval(ref, out, what, tol_memb=TOL_MEMB):
    hdr, rs = rows(out)
    exp_hdr = "u,w,footprint,x,y" + (",z" if ref.has_z else "") + \
        ",T,I,F,out_of_range"
    check(hdr == exp_hdr, f"{what}: header {hdr!r}")
    worst = 0.0
    nch = len(ref.chs)
    for r in rs:
        u, w, fp = Fr(r[0]), Fr(r[1]), r[2]
        check(len(r) == 3 + nch + 1, f"{what}: row width {r}")
        if fp not in FPS:
            continue
        flagged = set(r[-1].split("|")) - {"-"}
        for k, ch in enumerate(ref.chs):
            exact = ref.surf(fp, ch, u, w)
            err = abs(float(Fr(r[3 + k]) - exact))
            tol = tol_memb if ch in "TIF" else ref.coord_tol()
            if ch in "TIF":
                worst = max(worst, err)
                outside = exact < 0 or exact > 1
                if abs(float(exact)) > 1e-4 and abs(float(exact) - 1) > 1e-4:
                    check((ch in flagged) == outside,
                          f"{what}: flag {ch} at {r[:3]}: {r[-1]}")
            check(err <= tol, f"{what}: {fp} {ch} at ({r[0]},{r[1]}): "
                  f"{r[3 + k]} vs {float(exact):.9f} (err {err:.2e})")
    return worst


def main():
    paper = "examples/paper_4x4.csv"
    ref = Ref(paper)

    # -- help, version, usage errors (exit 1) --
    rc, out, err = run("--help")
    check(rc == 0 and "Usage: it2n COMMAND" in out, "--help")
    for cmd in ["check", "solve", "eval", "sample", "locate", "deriv", "plot",
                "export"]:
        rc, out, _ = run(cmd, "--help")
        check(rc == 0 and out.startswith(f"Usage: it2n {cmd} DATA.csv"),
              f"{cmd} --help")
    rc, out, _ = run("--version")
    check(rc == 0 and out.startswith("it2n "), "--version")
    for cmd in ["eval", "plot"]:  # after a command: the same line (cli_builtin_opt)
        rc2, out2, _ = run(cmd, "--version")
        check(rc2 == 0 and out2 == out, f"{cmd} --version is it2n --version's line")
    usage = [
        ([], ""),
        (["frobnicate", paper], "unknown command 'frobnicate'"),
        (["eval", paper], "eval needs at least one --at"),
        (["eval", paper, "--at", "1.5,0.5"],
         "--at '1.5,0.5': parameters must lie in [0,1]"),
        (["eval", paper, "--at", "0.5"],
         "--at '0.5': expected two numbers separated by a comma"),
        (["eval", paper, "--at", "a,b"], "--at 'a,b': not a decimal number"),
        (["eval", paper, "--at", "0,0", "--decimals", "10"],
         "--decimals '10': expected 0..9"),
        (["sample", paper, "--grid", "1x3"], "--grid '1x3': expected RxC"),
        (["sample", paper], "sample needs --grid RxC"),
        (["solve", paper, "--summary"], "--summary does not apply to solve"),
        (["check"], "missing DATA.csv"),
        (["check", paper, paper], "expected exactly one DATA.csv"),
        (["check", paper, "--bogus"], "unknown option '--bogus'"),
        (["eval", paper, "--at"], "option '--at' needs an argument"),
    ]
    for args, msg in usage:
        rc, out, err = run(*args)
        check(rc == 1 and msg in err and out == "",
              f"usage {args}: rc {rc} stderr {err!r}")

    # -- data errors (exit 2, FILE:LINE: message on stderr) --
    with tempfile.TemporaryDirectory() as tmp:
        lines = open(paper).read().split("\n")
        bad = os.path.join(tmp, "data.csv")

        def with_line(idx, text):
            ls = lines[:]
            ls[idx] = text
            open(bad, "w").write("\n".join(ls))
            return run("eval", bad, "--at", "0.5,0.5")

        # Line 70 of the paper file is (2,1,RL): header is line 1.
        check(lines[69].startswith("2,1,RL,"), "paper line 70 is (2,1,RL)")
        rc, out, err = with_line(69, "2,1,RL,11,11,1.2,0.4,0.1")
        check(rc == 2 and out == "" and err ==
              f"{bad}:70: T=1.2 outside [0,1] at (i=2,j=1,RL)\n",
              f"T range: {rc} {err!r}")
        rc, out, err = with_line(69, "2,1,RL,11,11,x,0.4,0.1")
        check(rc == 2 and err ==
              f"{bad}:70: T='x' is not a decimal number at (i=2,j=1,RL)\n",
              f"bad number: {err!r}")
        rc, out, err = with_line(69, "# removed")
        check(rc == 2 and err.startswith(
            f"{bad}: missing row at (i=2,j=1,RL)"), f"missing: {err!r}")
        rc, out, err = with_line(69, "2,1,RR,11,11,0.7,0.4,0.1")
        check(rc == 2 and err == f"{bad}:71: duplicate row at "
              "(i=2,j=1,RR) (first on line 70)\n", f"duplicate: {err!r}")
        f70 = lines[69].split(",")
        rc, out, err = with_line(69, ",".join(f70[:3] + ["-100"] + f70[4:]))
        check(rc == 2 and err.startswith(f"{bad}:70: x=-100 below R's x=")
              and "at (i=2,j=1,RL)" in err, f"order: {err!r}")
        rc, out, err = with_line(0, "i,j,fp,x,y,T,I,F")
        check(rc == 2 and err.startswith(f"{bad}:1: bad header"),
              f"header: {err!r}")
        rc, out, err = run("check", os.path.join(tmp, "nope.csv"))
        check(rc == 2 and "nope.csv: cannot open" in err, f"open: {err!r}")
        same = os.path.join(tmp, "same.csv")
        open(same, "w").write("i,j,footprint,x,y,T,I,F\n" + "".join(
            f"{i},{j},D,1,1,0,0,0\n" for i in range(2) for j in range(2)))
        rc, out, err = run("check", "--chord", same)
        check(rc == 2 and "degenerate chord-length" in err,
              f"degenerate: {err!r}")
        rc, out, err = run("check", same)
        check(rc == 0, f"coincident points are fine uniformly: {err!r}")

    # -- check / solve --
    rc, out, err = run("check", paper)
    check(rc == 0 and "ok: 4x4 grid (n=3, m=3), type-2" in out, "check ok")
    rc, out, err = run("solve", paper)
    hdr, rs = rows(out)
    check(rc == 0 and hdr == "i,j,footprint,x,y,T,I,F", "solve header")
    check(len(rs) == 16 * 7, "solve row count")
    for r in rs:
        for k, ch in enumerate(ref.chs):
            exact = ref.ctrl[(r[2], ch)][int(r[0])][int(r[1])]
            check(abs(float(Fr(r[3 + k]) - exact)) <= 1e-4,
                  f"solve {r[:3]} {ch}: {r[3 + k]} vs {float(exact)}")

    # -- eval against the exact reference --
    ats = ["0.5,0.5", "0,0", "1,1", "0.25,0.75", "0.123456,0.654321",
           "1,0.3", "0.999999,0.000001"]
    args = ["eval", paper]
    for a in ats:
        args += ["--at", a]
    rc, out, err = run(*args)
    check(rc == 0 and err == "", f"eval rc {rc} {err!r}")
    _, rs = rows(out)
    check(len(rs) == 7 * len(ats), "eval row count")
    check(all(len(x.split(".")[1]) == 6 for r in rs for x in r[3:8]),
          "6 decimals by default")
    compare_eval(ref, out, "paper eval")
    # 9 decimals so the comparison sees the core's error, not the rounding.
    rc, out, err = run(*args, "--decimals", "9")
    worst = compare_eval(ref, out, "paper eval --decimals 9")
    print(f"cli e2e: paper eval worst membership error {worst:.2e} "
          f"(limit {TOL_MEMB:.0e})")

    # --decimals 0..5: every value is its exact Q24 value (recovered from
    # the 9-decimal output: Q24 steps are 6e-8 apart) rounded to nearest,
    # ties away from zero, no "-0"; u, w keep 6 decimals.
    _, r9 = rows(out)
    q24 = [[round(Fr(x) * 2**24) for x in r[3:8]] for r in r9]
    for d in range(0, 6):
        rc, outd, err = run(*args, "--decimals", str(d))
        check(rc == 0 and err == "", f"eval --decimals {d}: rc {rc} {err!r}")
        _, rd = rows(outd)
        check(len(rd) == len(r9), f"eval --decimals {d}: row count")
        bad = 0
        for r, ks in zip(rd, q24):
            bad += any(len(x.split(".")[1]) != 6 for x in r[0:2])
            for x, k in zip(r[3:8], ks):
                v = Fr(k, 2**24) * 10**d
                n = int(abs(v) + Fr(1, 2)) * (1 if v >= 0 else -1)
                want = f"{'-' if n < 0 else ''}{abs(n) // 10**d}" + \
                    (f".{abs(n) % 10**d:0{d}d}" if d else "")
                bad += x != want          # never "-0.00"
        check(bad == 0, f"eval --decimals {d}: {bad} values not rounded "
              "exactly (or u, w not at 6 decimals)")

    # Interpolation: every data point is reproduced.
    args = ["eval", paper, "--decimals", "9"]
    for i in range(4):
        for j in range(4):
            args += ["--at", f"{Fr(i, 3).numerator / Fr(i, 3).denominator:.12f},"
                     f"{j / 3:.12f}"]
    rc, out, err = run(*args)
    _, rs = rows(out)
    check(all(len(x.split(".")[1]) == 9 for r in rs for x in r[3:8]),
          "--decimals 9")
    for idx, r in enumerate(rs):
        i, j = divmod(idx // 7, 4)
        for k, ch in enumerate(ref.chs):
            d = ref.data[(i, j, r[2])][ch]
            check(abs(float(Fr(r[3 + k]) - d)) <= 2e-5,
                  f"interpolates ({i},{j},{r[2]}) {ch}: {r[3 + k]} vs {d}")

    # --summary: 4 rows per point, bounds over {LL,D,RR} and {LR,D,RL}.
    rc, out, err = run("eval", paper, "--summary", "--at", "0.3,0.8")
    _, rs = rows(out)
    check(rc == 0 and [r[2] for r in rs] == FPS + [
        "upper_min", "upper_max", "lower_min", "lower_max"], "summary rows")
    by = {r[2]: r for r in rs}
    for k, ch in enumerate("TIF"):
        up = [Fr(by[f][5 + k]) for f in ("LL", "D", "RR")]
        lo = [Fr(by[f][5 + k]) for f in ("LR", "D", "RL")]
        check(Fr(by["upper_min"][5 + k]) == min(up) and
              Fr(by["upper_max"][5 + k]) == max(up) and
              Fr(by["lower_min"][5 + k]) == min(lo) and
              Fr(by["lower_max"][5 + k]) == max(lo), f"summary {ch}")
    check(by["upper_min"][3:5] == ["", ""], "summary rows leave x,y empty")
    # With z: every row under the 10-column header (a summary row had 11
    # fields), T, I, F of the summary rows in the T, I, F columns.
    for cmd in (["eval", "examples/z_3x3.csv", "--at", "0.3,0.8", "--at", "1,0"],
                ["sample", "examples/z_3x3.csv", "--grid", "3x2"]):
        rc, out, err = run(*cmd, "--summary")
        hdr, rs = rows(out)
        cols = hdr.split(",")
        check(rc == 0 and cols == ["u", "w", "footprint", "x", "y", "z", "T",
                                   "I", "F", "out_of_range"],
              f"{cmd[0]} --summary with z: header {hdr} {err}")
        check(rs and all(len(r) == len(cols) for r in rs),
              f"{cmd[0]} --summary with z: rows of {sorted({len(r) for r in rs})}"
              f" fields under {len(cols)} columns")
        for at in {tuple(r[:2]) for r in rs}:
            by = {r[2]: r for r in rs if tuple(r[:2]) == at}
            check(by["upper_min"][3:6] == ["", "", ""],
                  "summary rows leave x,y,z empty")
            for k, ch in enumerate("TIF"):
                c = cols.index(ch)
                up = [Fr(by[f][c]) for f in ("LL", "D", "RR")]
                lo = [Fr(by[f][c]) for f in ("LR", "D", "RL")]
                check(Fr(by["upper_min"][c]) == min(up) and
                      Fr(by["upper_max"][c]) == max(up) and
                      Fr(by["lower_min"][c]) == min(lo) and
                      Fr(by["lower_max"][c]) == max(lo),
                      f"{cmd[0]} --summary with z: {ch} in its column at {at}")

    # stdin
    rc, out2, err = run("eval", "-", "--at", "0.5,0.5", stdin=open(paper).read())
    rc1, out1, _ = run("eval", paper, "--at", "0.5,0.5")
    check(rc == 0 and out2 == out1, "stdin gives the same output")

    # -- other examples: type-1 (overshoot flagged), z, chord --
    for path, chord in [("examples/type1_4x3.csv", False),
                        ("examples/z_3x3.csv", False),
                        ("examples/chord_5x4.csv", False),
                        ("examples/chord_5x4.csv", True),
                        (paper, True)]:
        r2 = Ref(path, chord)
        args = ["eval", path] + (["--chord"] if chord else [])
        for a in ["0.5,0.5", "0.1,0.9", "0.7,0.2", "1,0"]:
            args += ["--at", a]
        rc, out, err = run(*args)
        check(rc == 0, f"{path} eval rc {rc} {err}")
        compare_eval(r2, out, f"{path}{' --chord' if chord else ''}")
    # Degree 7 x 7 (the maximum), smooth data: within 1e-4.
    big = "tests/cli/corpus/max_degree.csv"
    r7 = Ref(big)
    args = ["eval", big, "--decimals", "9"]
    for a in ["0.5,0.5", "0.05,0.95", "0.93,0.11", "0.3,0.3"]:
        args += ["--at", a]
    rc, out, err = run(*args)
    check(rc == 0, f"7x7 eval rc {rc} {err}")
    worst7 = compare_eval(r7, out, "7x7 eval", tol_memb=1e-4)
    print(f"cli e2e: degree 7x7 eval worst membership error {worst7:.2e} "
          "(limit 1e-04)")

    rc, out, _ = run("eval", "examples/type1_4x3.csv", "--at", "0.5,0.5")
    _, rs = rows(out)
    check(len(rs) == 1 and rs[0][2] == "D" and rs[0][-1] == "T" and
          Fr(rs[0][5]) > 1, f"type-1 overshoot flagged: {rs}")

    # -- sample: grid order and agreement with eval --
    rc, out, err = run("sample", paper, "--grid", "3x2")
    hdr, rs = rows(out)
    check(rc == 0 and hdr == "u,w,footprint,x,y,T,I,F,out_of_range",
          "sample header")
    check(len(rs) == 3 * 2 * 7, "sample row count")
    check([(r[0], r[1]) for r in rs[::7]] == [
        ("0.000000", "0.000000"), ("0.000000", "1.000000"),
        ("0.500000", "0.000000"), ("0.500000", "1.000000"),
        ("1.000000", "0.000000"), ("1.000000", "1.000000")], "sample order")
    compare_eval(ref, out, "sample")

    # -- deriv against the exact derivative --
    rc, out, err = run("deriv", paper, "--at", "0.5,0.5", "--at", "0.2,0.9")
    hdr, rs = rows(out)
    check(rc == 0 and hdr == "u,w,footprint,wrt,x,y,T,I,F", "deriv header")
    check(len(rs) == 2 * 7 * 2, "deriv row count")
    for r in rs:
        u, w = Fr(r[0]), Fr(r[1])
        for k, ch in enumerate(ref.chs):
            exact = ref.surf(r[2], ch, u, w, du=r[3] == "u", dw=r[3] == "w")
            tol = 1e-4 if ch in "TIF" else 1e-3
            check(abs(float(Fr(r[4 + k]) - exact)) <= tol,
                  f"deriv {r[:4]} {ch}: {r[4 + k]} vs {float(exact)}")

    # -- locate: back to the parameters of an evaluated point --
    rc, out, _ = run("eval", paper, "--at", "0.3,0.6")
    _, rs = rows(out)
    d = next(r for r in rs if r[2] == "D")
    rc, out, err = run("locate", paper, "--at", f"{d[3]},{d[4]}",
                       "--at", "100,100")
    hdr, rs = rows(out)
    check(rc == 0 and hdr == "x,y,footprint,u,w,T,I,F,status",
          f"locate header {hdr}")
    dl = next(r for r in rs if r[2] == "D" and r[0] == d[3])
    check(dl[-1] == "inside" and abs(float(Fr(dl[3])) - 0.3) < 1e-4 and
          abs(float(Fr(dl[4])) - 0.6) < 1e-4 and
          abs(float(Fr(dl[5]) - Fr(d[5]))) < 1e-4, f"locate D: {dl}")
    check(all(r[-1] == "outside" for r in rs if r[0] == "100.000000"),
          "locate far away: outside")
    rc, out, _ = run("locate", "examples/z_3x3.csv", "--at", "4,4")
    hdr, _ = rows(out)
    check(hdr == "x,y,footprint,u,w,z,T,I,F,status", "locate z header")

    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
