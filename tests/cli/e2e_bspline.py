#!/usr/bin/env python3
"""End-to-end tests of `it2n --kind bspline` (issue 21).

Runs the binary given as argv[1] (from the repository root). Numbers are
checked against an independent exact reference: the not-a-knot cubic spline
defined by its equations (interpolation at every data point, no jump of the
third derivative at the second and second-to-last knots; the line or the
parabola through 2 or 3 points, as SciPy's CubicSpline and MATLAB's spline)
solved with fractions.Fraction by Gaussian elimination, tensor product rows
then columns, evaluated with the uniform cubic B-spline basis.
"""
import os
import subprocess
import sys
import tempfile
from fractions import Fraction as Fr

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from e2e import FPS, load, rows  # noqa: E402,F401  (one copy, tests/cli/e2e.py)
from it2ntest import report  # noqa: E402  (on the path since e2e's import)

BIN = sys.argv[1]
TOL_MEMB = 2e-7
R = report.Report("cli-e2e-bspline", quiet_ok=True)  # hundreds of checks: failures only
check = R.check


def run(*args, stdin=None):
    # the 256x256 cases need more than e2e.py's 60 s on a loaded machine
    p = subprocess.run([BIN, *args], capture_output=True, text=True,
                       input=stdin, timeout=120)
    return p.returncode, p.stdout, p.stderr


# ---- Exact reference ------------------------------------------------------

_systems = {}


def system(n):
    """Rows of the defining equations for n intervals (n + 3 unknowns)."""
    if n in _systems:
        return _systems[n]
    d = n + 3
    a = []
    for i in range(n + 1):
        r = [Fr(0)] * d
        r[i], r[i + 1], r[i + 2] = Fr(1, 6), Fr(4, 6), Fr(1, 6)
        a.append(r)
    if n >= 3:
        conds = [(0, [1, -4, 6, -4, 1]), (n - 2, [1, -4, 6, -4, 1])]
    elif n == 2:
        conds = [(0, [-1, 3, -3, 1]), (1, [-1, 3, -3, 1])]
    else:
        conds = [(0, [1, -2, 1]), (1, [1, -2, 1])]
    for start, cf in conds:
        r = [Fr(0)] * d
        for k, c in enumerate(cf):
            r[start + k] = Fr(c)
        a.append(r)
    _systems[n] = a
    return a


def solve_line(n, y):
    a = [row[:] + [y[i] if i <= n else Fr(0)] for i, row in enumerate(system(n))]
    d = n + 3
    for col in range(d):
        p = next(r for r in range(col, d) if a[r][col] != 0)
        a[col], a[p] = a[p], a[col]
        for r in range(d):
            if r != col and a[r][col] != 0:
                f = a[r][col] / a[col][col]
                a[r] = [x - f * z for x, z in zip(a[r], a[col])]
    return [a[i][d] / a[i][i] for i in range(d)]


class Ref:
    def __init__(self, path, fps=None, chs=None):
        self.data, self.z = load(path)
        self.n = max(k[0] for k in self.data)
        self.m = max(k[1] for k in self.data)
        self.fps = sorted({k[2] for k in self.data}, key=FPS.index)
        if fps:
            self.fps = [f for f in self.fps if f in fps]
        self.chs = ["x", "y"] + (["z"] if self.z else []) + ["T", "I", "F"]
        if chs:
            self.chs = [c for c in self.chs if c in chs]
        self.coef = {}
        for fp in self.fps:
            for ch in self.chs:
                g = [solve_line(self.m, [self.data[(i, j, fp)][ch]
                                         for j in range(self.m + 1)])
                     for i in range(self.n + 1)]
                cols = [solve_line(self.n, [g[i][s] for i in range(self.n + 1)])
                        for s in range(self.m + 3)]
                self.coef[(fp, ch)] = [[cols[s][r] for s in range(self.m + 3)]
                                       for r in range(self.n + 3)]
        self.maxabs = max(abs(v[c]) for v in self.data.values()
                          for c in ("x", "y", "z") if c in v)

    @staticmethod
    def basis(N, u):
        x = u * N
        k = min(int(x), N - 1)
        t = x - k
        b = [(1 - t) ** 3 / 6, (3 * t ** 3 - 6 * t * t + 4) / 6,
             (-3 * t ** 3 + 3 * t * t + 3 * t + 1) / 6, t ** 3 / 6]
        db = [-(1 - t) ** 2 / 2 * N, (Fr(3, 2) * t * t - 2 * t) * N,
              (-Fr(3, 2) * t * t + t + Fr(1, 2)) * N, t * t / 2 * N]
        return k, b, db

    def surf(self, fp, ch, u, w, du=False, dw=False):
        k, bu, dbu = self.basis(self.n, u)
        l, bw, dbw = self.basis(self.m, w)
        cu = dbu if du else bu
        cw = dbw if dw else bw
        c = self.coef[(fp, ch)]
        return sum(cu[a] * cw[b] * c[k + a][l + b]
                   for a in range(4) for b in range(4))

    def tol(self, ch):
        if ch in ("T", "I", "F"):
            return TOL_MEMB
        return 1e-6 * float(self.maxabs) + 1e-7


def compare(ref, out, what, printed=5e-10, scale=1.0):
    hdr, rs = rows(out)
    cols = hdr.split(",")
    n = 0
    for r in rs:
        if r[2] not in ref.fps:
            continue
        u, w = Fr(r[0]), Fr(r[1])
        for ch in ref.chs:
            got = Fr(r[cols.index(ch)])
            want = ref.surf(r[2], ch, u, w)
            err = abs(float(got - want))
            n += 1
            if err > scale * ref.tol(ch) + printed:
                check(False, "%s: %s.%s at (%s,%s): %s vs %.12f (err %.3e)"
                      % (what, r[2], ch, r[0], r[1], r[cols.index(ch)],
                         float(want), err))
    check(n > 0, what + ": rows compared")
    return n


def write_csv(path, n, m, fps, z, f):
    with open(path, "w") as fh:
        fh.write("i,j,footprint,x,y%s,T,I,F\n" % (",z" if z else ""))
        for i in range(n + 1):
            for j in range(m + 1):
                for k, fp in enumerate(fps):
                    vals = f(i, j, k)
                    if not z:
                        vals = vals[:2] + vals[3:]
                    fh.write("%d,%d,%s,%s\n" % (i, j, fp, ",".join(
                        "%.6f" % v for v in vals)))


def main():
    tmp = tempfile.mkdtemp(prefix="it2n-bs-")
    ats = ["0,0", "1,1", "0,1", "0.5,0.5", "0.123457,0.876543", "0.333333,0.7",
           "0.999999,0.000001", "0.6,0.25"]

    # The paper's 4x4 grid: not-a-knot through 4 points is the cubic
    # through them, so the B-spline equals the bicubic Bezier interpolant.
    at = sum((["--at", a] for a in ats), [])
    rc, bs, err = run("eval", "--kind", "bspline", "examples/paper_4x4.csv",
                      "--decimals", "9", *at)
    check(rc == 0, "paper bspline eval rc=%d %s" % (rc, err))
    rc, bz, err = run("eval", "examples/paper_4x4.csv", "--decimals", "9", *at)
    check(rc == 0, "paper bezier eval rc=%d" % rc)
    for a, b in zip(rows(bs)[1], rows(bz)[1]):
        for x, y in zip(a[3:-1], b[3:-1]):
            check(abs(float(x) - float(y)) < 1e-6,
                  "paper: bspline %s vs bezier %s" % (x, y))
    ref = Ref("examples/paper_4x4.csv")
    compare(ref, bs, "paper 4x4 bspline")

    # Generated 6x5 type-2 grid with z: exact reference at many points.
    p65 = os.path.join(tmp, "g65.csv")

    def smooth(i, j, k):
        s = k - 3
        return [10 * i + 0.3 * s + 0.1 * ((i * j) % 3), 7 * j + 0.2 * s,
                ((i - 3) ** 2 - j * j * 0.5 + s * 0.05) / 7,
                0.5 + 0.3 * ((i * 7 + j * 3) % 5 - 2) / 2 - 0.01 * abs(s),
                0.2 + 0.05 * ((i + 2 * j) % 3), 0.1 + 0.02 * abs(s)]
    write_csv(p65, 6, 5, FPS, True, smooth)
    grid_at = ["%d/%d" % (a, 9) for a in range(10)]
    at = sum((["--at", "%.6f,%.6f" % (a / 9, b / 7)]
              for a in range(10) for b in range(8)), [])
    rc, out, err = run("eval", "--kind", "bspline", p65, "--decimals", "9", *at)
    check(rc == 0, "g65 eval rc=%d %s" % (rc, err))
    ref65 = Ref(p65)
    compare(ref65, out, "6x5 type-2 x,y,z")
    del grid_at

    # solve prints the coefficients c_{-1..n+1, -1..m+1}
    rc, out, err = run("solve", "--kind", "bspline", p65, "--decimals", "9")
    check(rc == 0, "g65 solve rc=%d" % rc)
    hdr, rs = rows(out)
    check(len(rs) == 9 * 8 * 7, "solve rows %d" % len(rs))
    cols = hdr.split(",")
    # A coefficient moves by up to 243 times the data's Q24 rounding (2^-25:
    # the not-a-knot end coefficients), plus 1e-6 of its net's largest.
    worst = 0.0
    for r in rs:
        i, j = int(r[0]), int(r[1])
        for ch in ref65.chs:
            net = ref65.coef[(r[2], ch)]
            big = max(abs(float(c)) for row in net for c in row)
            want = net[i + 1][j + 1]
            e = abs(float(Fr(r[cols.index(ch)]) - want))
            worst = max(worst, e / (243 * 2.0 ** -25 + 1e-6 * big + 5e-10))
    check(worst <= 1.0, "solve coefficients worst %.3f of tol" % worst)
    print("e2e_bspline: 6x5 coefficients worst %.3f of tolerance" % worst)

    # deriv against the exact derivatives (one span is 1/n: 4 n tol)
    at = ["--at", "0.3,0.6", "--at", "1,0", "--at", "0.71,0.05"]
    rc, out, err = run("deriv", "--kind", "bspline", p65, "--decimals", "9", *at)
    check(rc == 0, "deriv rc=%d %s" % (rc, err))
    hdr, rs = rows(out)
    cols = hdr.split(",")
    for r in rs:
        u, w = Fr(r[0]), Fr(r[1])
        for ch in ref65.chs:
            want = ref65.surf(r[2], ch, u, w, du=r[3] == "u", dw=r[3] == "w")
            e = abs(float(Fr(r[cols.index(ch)]) - want))
            check(e <= 4 * 6 * ref65.tol(ch) + 1e-9,
                  "deriv %s.%s d%s err %.3e" % (r[2], ch, r[3], e))

    # 2 and 3 points in a direction: the line and the parabola
    for n, m in ((1, 1), (2, 1), (1, 2), (2, 2), (3, 2)):
        p = os.path.join(tmp, "small%d%d.csv" % (n, m))
        write_csv(p, n, m, ["D"], False,
                  lambda i, j, k: [3 * i - 0.5 * i * i + j, 2 * j + i * j * 0.25,
                                   0, 0.2 + 0.1 * i + 0.05 * j * j,
                                   0.5 - 0.05 * i * j, 0.3])
        at = sum((["--at", a] for a in ats), [])
        rc, out, err = run("eval", "--kind", "bspline", p, "--decimals", "9", *at)
        check(rc == 0, "small %dx%d rc=%d %s" % (n, m, rc, err))
        compare(Ref(p), out, "small %dx%d" % (n, m))

    # The 64x64 survey: every grid node reproduces its data (sample on a
    # 64x64 grid hits u = i/63 exactly). Values between nodes at this size
    # are checked by tests/core/test_bspline.c (long double reference).
    sv = "examples/survey_64x64.csv"
    rc, out, err = run("check", "--kind", "bspline", sv)
    check(rc == 0 and "64x64 grid" in out, "survey check: %s %s" % (out, err))
    data, _ = load(sv)
    rc, out, err = run("sample", "--kind", "bspline", sv, "--grid", "64x64",
                       "--decimals", "9")
    check(rc == 0, "survey sample rc=%d" % rc)
    hdr, rs = rows(out)
    cols = hdr.split(",")
    check(len(rs) == 64 * 64 * 7, "survey sample rows %d" % len(rs))
    worst = 0.0
    for k, r in enumerate(rs):
        i, j = (k // 7) // 64, (k // 7) % 64
        d = data[(i, j, r[2])]
        for ch in ("x", "y", "z", "T", "I", "F"):
            tol = TOL_MEMB if ch in "TIF" else 1e-6 * 630 + 1e-7
            worst = max(worst, abs(float(Fr(r[cols.index(ch)]) - d[ch])) / tol)
    check(worst <= 1.0, "survey nodes: worst %.3f of tol" % worst)
    print("e2e_bspline: survey 64x64 nodes worst %.3f of tolerance" % worst)

    # Errors: what, where, what to do; exit 2 (data) or 1 (usage)
    bad = os.path.join(tmp, "bad.csv")
    with open(bad, "w") as fh:
        fh.write("i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,0.5,0.5\n"
                 "256,0,D,1,0,0.5,0.5,0.5\n")
    rc, out, err = run("check", "--kind", "bspline", bad)
    check(rc == 2 and "bad.csv:3: i='256' is not a grid index 0..255 "
          "(IT2N_BSPLINE_MAX_N)" in err, "index limit: %d %s" % (rc, err))
    with open(bad, "w") as fh:
        fh.write("i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,0.5,0.5\n"
                 "1,1,D,1,1,0.5,0.5,0.5\n0,1,D,0,1,0.5,0.5,0.5\n")
    rc, out, err = run("check", "--kind", "bspline", bad)
    check(rc == 2 and "missing row at (i=1,j=0,D)" in err,
          "missing: %d %s" % (rc, err))
    with open(bad, "w") as fh:
        fh.write("i,j,footprint,x,y,T,I,F\n0,0,D,0,0,0.5,0.5,0.5\n"
                 "1,1,D,1,1,0.5,1.5,0.5\n")
    rc, out, err = run("check", "--kind", "bspline", bad)
    check(rc == 2 and "bad.csv:3: I=1.5 outside [0,1]" in err,
          "range: %d %s" % (rc, err))
    rc, out, err = run("check", "--kind", "spline", p65)
    check(rc == 1 and "--kind 'spline': expected bezier or bspline" in err,
          "bad kind: %d %s" % (rc, err))
    rc, out, err = run("check", "--kind", "bspline", "--chord", p65)
    check(rc == 1 and "uniform parameters only" in err, "chord: %s" % err)
    # export samples the B-spline surface: every vertex of footprint D at
    # the grid's nodes is the sample command's value there
    rc, out, err = run("export", "--kind", "bspline", p65, "--format", "csv",
                       "--grid", "3x3", "--footprint", "D", "--decimals", "6")
    rc2, out2, err2 = run("sample", "--kind", "bspline", p65, "--grid", "3x3",
                          "--footprint", "D", "--decimals", "6")
    check(rc == 0 and rc2 == 0, "export/sample: %d %s %d %s" % (rc, err, rc2, err2))
    xs = sorted(set(l.split(",")[-3] for l in out.splitlines()[1:] if l))
    check(len(out.splitlines()) > 9 and xs and all(
        any(x in l for l in out2.splitlines()) for x in xs),
        "export values not those of sample: %s / %s" % (out[:300], out2[:300]))

    # locate: the (u, w) of a surface point of footprint D is found again
    u0, w0 = Fr(3, 10), Fr(3, 5)
    xd = ref65.surf("D", "x", u0, w0)
    yd = ref65.surf("D", "y", u0, w0)
    rc, out, err = run("locate", "--kind", "bspline", p65, "--decimals", "9",
                       "--at", "%.9f,%.9f" % (float(xd), float(yd)))
    check(rc == 0, "locate rc=%d %s" % (rc, err))
    hdr, rs = rows(out)
    cols = hdr.split(",")
    d = [r for r in rs if r[2] == "D"]
    check(len(d) == 1 and d[0][-1] == "inside", "locate D: %s" % out)
    if d:
        check(abs(float(Fr(d[0][3]) - u0)) < 1e-6 and
              abs(float(Fr(d[0][4]) - w0)) < 1e-6,
              "locate D (u,w) = (%s,%s), want (0.3,0.6)" % (d[0][3], d[0][4]))
        want_t = ref65.surf("D", "T", u0, w0)
        check(abs(float(Fr(d[0][cols.index("T")]) - want_t)) < 1e-6,
              "locate D T %s vs %.9f" % (d[0][cols.index("T")], float(want_t)))
    rc, out, err = run("check", sv)
    check(rc == 2 and "is not a grid index 0..7" in err, "bezier limit: %s" % err)

    sys.exit(R.finish())


if __name__ == "__main__":
    main()
