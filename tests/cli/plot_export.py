#!/usr/bin/env python3
"""Tests of `it2n plot`, `it2n export` and `sample --footprint`.

Usage: plot_export.py BIN [--figure docs/img/paper_T.png ...]

plot: the paper example rendered as PNG and SVG; each file must be a valid
image of the requested size that is not blank (PNG: IHDR parsed, IDAT
inflated with zlib and unfiltered, pixel variety counted; SVG: parsed with
xml.etree, plot elements counted). Errors: missing gnuplot, failing gnuplot,
data errors, usage errors.

export: every format parsed back by the small parsers below (VTK legacy
POLYDATA, Wavefront OBJ, CSV) and every vertex compared with `it2n sample`
at the same grid nodes (the same exact decimal text).
"""
import os
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
import zlib

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from it2ntest import report  # noqa: E402

BIN = os.path.abspath(sys.argv[1])
FIGURES = [sys.argv[k + 1] for k, a in enumerate(sys.argv) if a == "--figure"]
PAPER = "examples/paper_4x4.csv"
FPS = ["LL", "LR", "L", "D", "R", "RL", "RR"]
MEMB = ["T", "I", "F"]
R = report.Report("cli-plot", quiet_ok=True)  # hundreds of checks: failures only
check = R.check


def run(*args, env=None):
    p = subprocess.run([BIN, *args], capture_output=True, text=True,
                       timeout=120, env=env)
    return p.returncode, p.stdout, p.stderr


# ---- images ---------------------------------------------------------------

def png_info(path):
    """(width, height, distinct pixel values, fraction unlike the corner)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG signature")
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        ln, typ = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + ln]
        crc = struct.unpack(">I", data[pos + 8 + ln:pos + 12 + ln])[0]
        if zlib.crc32(typ + body) & 0xffffffff != crc:
            raise ValueError(f"bad CRC in {typ!r}")
        if typ == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif typ == b"IDAT":
            idat += body
        elif typ == b"IEND":
            break
        pos += 12 + ln
    w, h, depth, ctype, _, _, interlace = ihdr
    if depth != 8 or interlace != 0 or ctype not in (0, 2, 3, 4, 6):
        raise ValueError(f"unsupported PNG depth {depth} type {ctype}")
    bpp = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}[ctype]
    raw = zlib.decompress(idat)
    stride = w * bpp
    if len(raw) != h * (stride + 1):
        raise ValueError("IDAT size does not match IHDR")
    prev = bytearray(stride)
    pixels = set()
    first, unlike, total = None, 0, 0
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pr = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pr) & 255
            elif f != 0:
                raise ValueError(f"bad filter {f}")
        for x in range(0, stride, bpp):
            px = bytes(line[x:x + bpp])
            pixels.add(px)
            if first is None:
                first = px
            unlike += px != first
            total += 1
        prev = line
    return w, h, len(pixels), unlike / total


def check_png(path, w, h, what):
    try:
        pw, ph, colours, ink = png_info(path)
    except (OSError, ValueError, TypeError, zlib.error) as e:
        check(False, f"{what}: not a valid PNG: {e}")
        return
    check((pw, ph) == (w, h), f"{what}: size {pw}x{ph}, expected {w}x{h}")
    check(colours >= 16, f"{what}: only {colours} distinct pixel values")
    check(ink >= 0.02, f"{what}: nearly blank ({ink:.1%} drawn)")


def check_svg(path, w, h, what):
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        check(False, f"{what}: not valid XML: {e}")
        return
    check(root.tag.endswith("svg"), f"{what}: root is {root.tag}")
    check((root.get("width"), root.get("height")) == (str(w), str(h)),
          f"{what}: size {root.get('width')}x{root.get('height')}")
    drawn = [e for e in root.iter()
             if e.tag.split("}")[-1] in ("path", "polyline", "polygon")]
    texts = [e for e in root.iter() if e.tag.split("}")[-1] == "text"]
    check(len(drawn) >= 50, f"{what}: only {len(drawn)} plot elements")
    check(len(texts) >= 10, f"{what}: only {len(texts)} text elements")


def test_plot(tmp):
    cases = [
        (["--membership", "T"], "T.png", 900, 700),
        (["--membership", "I"], "I.png", 900, 700),
        (["--membership", "F", "--grid", "11x9"], "F.png", 900, 700),
        (["--membership", "all", "--size", "1200x800"], "all.png", 1200, 800),
        ([], "default.svg", 1500, 600),
        (["--membership", "T", "--footprint", "LL,D,RR", "--nets"], "T3.svg", 900, 700),
        (["--interval", "--membership", "I"], "band_I.png", 1000, 500),
        (["--interval", "--grid", "15x15", "--size", "640x480"],
         "band_T.svg", 640, 480),
    ]
    for args, name, w, h in cases:
        out = os.path.join(tmp, name)
        rc, so, se = run("plot", PAPER, "-o", out, *args)
        check(rc == 0 and so == "" and se == "",
              f"plot {args}: rc {rc} stderr {se!r}")
        if name.endswith(".png"):
            check_png(out, w, h, f"plot {args}")
        else:
            check_svg(out, w, h, f"plot {args}")
    # Quotes in the output name and in TMPDIR reach gnuplot intact.
    odd = os.path.join(tmp, "it's here")
    os.mkdir(odd)
    out = os.path.join(odd, "a 'b'.png")
    rc, _, se = run("plot", PAPER, "-o", out,
                    env=dict(os.environ, TMPDIR=odd))
    check(rc == 0 and os.listdir(odd) == ["a 'b'.png"],
          f"quotes in names: {rc} {se!r} {os.listdir(odd)}")
    check_png(out, 1500, 600, "quotes in names")
    rc, _, se = run("plot", PAPER, "--interval", "-o", out,
                    env=dict(os.environ, TMPDIR=odd))
    check(rc == 0 and os.listdir(odd) == ["a 'b'.png"],
          f"interval, quotes in names: {rc} {se!r}")
    check_png(out, 1000, 500, "interval, quotes in names")
    out = os.path.join(tmp, "type1.png")
    rc, _, se = run("plot", "examples/type1_4x3.csv", "-o", out)
    check(rc == 0, f"type-1 plot: {se!r}")
    check_png(out, 1500, 600, "type-1 plot")

    # Errors: gnuplot missing or failing, bad data, bad usage.
    out = os.path.join(tmp, "err.png")
    env = dict(os.environ, PATH=os.path.join(tmp, "empty"))
    rc, _, se = run("plot", PAPER, "-o", out, env=env)
    check(rc == 2 and "cannot run gnuplot" in se and "gnuplot-nox" in se and
          not os.path.exists(out), f"missing gnuplot: {rc} {se!r}")
    env = dict(os.environ, IT2N_GNUPLOT="/bin/false")
    rc, _, se = run("plot", PAPER, "-o", out, env=env)
    check(rc == 2 and "/bin/false failed (exit status 1)" in se and
          not os.path.exists(out), f"failing gnuplot: {rc} {se!r}")
    bad = os.path.join(tmp, "bad.csv")
    lines = open(PAPER).read().split("\n")
    lines[69] = "2,1,RL,11,11,1.2,0.4,0.1"
    open(bad, "w").write("\n".join(lines))
    rc, _, se = run("plot", bad, "-o", out)
    check(rc == 2 and se == f"{bad}:70: T=1.2 outside [0,1] at (i=2,j=1,RL)\n"
          and not os.path.exists(out), f"plot data error: {se!r}")
    rc, _, se = run("plot", PAPER, "-o", os.path.join(tmp, "no/dir/x.png"))
    check(rc == 2 and "cannot create" in se, f"unwritable output: {se!r}")
    rc, _, se = run("plot", "examples/type1_4x3.csv", "--interval", "-o", out)
    check(rc == 2 and "type-1 model" in se, f"type-1 interval: {se!r}")
    usage = [
        (["plot", PAPER], "plot needs -o FILE.png or -o FILE.svg"),
        (["plot", PAPER, "-o", "x.jpg"], "the name must end in .png or .svg"),
        (["plot", PAPER, "-o", out, "--membership", "X"],
         "--membership 'X': expected T, I, F or all"),
        (["plot", PAPER, "-o", out, "--interval", "--membership", "all"],
         "--interval needs one membership"),
        (["plot", PAPER, "-o", out, "--interval", "--footprint", "D"],
         "no --footprint"),
        (["plot", PAPER, "-o", out, "--grid", "1002x3"], "at most 1001x1001"),
        (["plot", PAPER, "-o", out, "--size", "100x100"], "--size '100x100'"),
        (["plot", PAPER, "-o", out, "--footprint", "D,X"],
         "--footprint 'D,X': expected names"),
        (["plot", PAPER, "-o", out, "--format", "vtk"],
         "--format does not apply to plot"),
        (["eval", PAPER, "--at", "0,0", "-o", out], "-o does not apply"),
    ]
    for args, msg in usage:
        rc, so, se = run(*args)
        check(rc == 1 and msg in se and so == "" and not os.path.exists(out),
              f"usage {args}: rc {rc} {se!r}")
    rc, so, _ = run("plot", "--help")
    check(rc == 0 and so.startswith("Usage: it2n plot DATA.csv -o"),
          "plot --help")


def plot_files(tmp, *args):
    """Run it2n plot through a gnuplot wrapper that keeps the script and
    data files; returns {name: text}."""
    keep = tempfile.mkdtemp(dir=tmp)
    wrap = os.path.join(tmp, "gp_keep.sh")
    with open(wrap, "w") as f:
        f.write('#!/bin/sh\ncp "$(dirname "$1")"/* "$KEEP"/ && exec gnuplot "$1"\n')
    os.chmod(wrap, 0o755)
    out = os.path.join(keep, "fig.png")
    rc, _, se = run("plot", PAPER, "-o", out, *args,
                    env=dict(os.environ, IT2N_GNUPLOT=wrap, KEEP=keep))
    check(rc == 0, f"plot {args} (kept): {rc} {se!r}")
    return {n: open(os.path.join(keep, n)).read() for n in os.listdir(keep)
            if n.endswith((".gp", ".dat"))}


def columns(text, col):
    return [float(ln.split()[col]) for ln in text.split("\n")
            if ln.strip() and not ln.startswith("#") and ln.split()[col] != "?"]


def zranges(script):
    return [tuple(float(v) for v in ln[len("set zrange ["):-1].split(":"))
            for ln in script.split("\n") if ln.startswith("set zrange [")]


def test_figures(tmp):
    """What the figure shows (issue 18): the z axis spans the surfaces and
    data points, not the control nets; hidden lines; every data point
    marked; three panels for all; the band map over the region it covers."""
    csv = [ln.split(",") for ln in open(PAPER).read().strip().split("\n")[1:]]
    data_t = [float(f[-3]) for f in csv]
    f = plot_files(tmp, "--membership", "T")
    surf_t = columns(f["surfaces.dat"], 2)
    lo, hi = min(surf_t + data_t), max(surf_t + data_t)
    zr = zranges(f["plot.gp"])
    check(len(zr) == 1 and lo - (hi - lo) / 8 - 0.05 <= zr[0][0] <= lo and
          hi <= zr[0][1] <= hi + (hi - lo) / 8 + 0.05,
          f"T z range {zr} for surfaces and data in [{lo}, {hi}]")
    nets_t = columns(f["nets.dat"], 2)
    check(min(nets_t) < zr[0][0] or max(nets_t) > zr[0][1],
          "the paper's nets overshoot the surfaces: this check cannot fail otherwise")
    check("set hidden3d" in f["plot.gp"] and " nets index" not in f["plot.gp"],
          "surfaces with hidden lines, no nets unless asked")
    check(sorted(columns(f["points.dat"], 2)) == sorted(data_t),
          "every data point marked, at its T")
    title = [ln for ln in f["plot.gp"].split("\n") if ln.startswith("set title")][0]
    check(len(title) - len("set title ''") <= 80, f"title fits: {title!r}")
    f = plot_files(tmp, "--membership", "T", "--nets")
    zr = zranges(f["plot.gp"])
    nets_t = columns(f["nets.dat"], 2)
    check(len(zr) == 1 and zr[0][0] <= min(nets_t) and max(nets_t) <= zr[0][1] and
          " nets index" in f["plot.gp"], f"--nets: z range {zr} holds the nets")
    f = plot_files(tmp)
    zr = zranges(f["plot.gp"])
    spans = [(min(columns(f["surfaces.dat"], c) + columns(f["points.dat"], c)),
              max(columns(f["surfaces.dat"], c) + columns(f["points.dat"], c))) for c in (2, 3, 4)]
    check("layout 1,3" in f["plot.gp"] and len(zr) == 3 and
          all(a - 0.1 <= z[0] <= a and b <= z[1] <= b + 0.1 for z, (a, b) in zip(zr, spans)),
          f"all: three panels, each scaled to its membership: {zr} vs {spans}")
    f = plot_files(tmp, "--interval", "--membership", "T")
    band = [ln.split() for ln in f["band.dat"].split("\n") if ln.strip() and not ln.startswith("#")]
    unknown = sum(r[2] == "?" and r[3] == "?" for r in band) / len(band)
    check(len(band) == 81 * 81 and unknown < 0.25,
          f"band map: {len(band)} nodes, {unknown:.0%} outside every band (cropped to the region)")


# ---- meshes ---------------------------------------------------------------

def sample_table(path, grid, extra=()):
    """{(r, c, fp): (u, w, x, y[, z], T, I, F)} from `it2n sample`."""
    rows, cols = map(int, grid.split("x"))
    rc, out, err = run("sample", path, "--grid", grid, *extra)
    check(rc == 0, f"sample {path}: {err!r}")
    lines = out.strip().split("\n")
    hdr = lines[0].split(",")
    table, node, last = {}, -1, None
    for ln in lines[1:]:
        f = ln.split(",")
        if (f[0], f[1]) != last:
            node, last = node + 1, (f[0], f[1])
        r, c = divmod(node, cols)
        table[(r, c, f[2])] = dict(zip(hdr, f))
    check(node + 1 == rows * cols, f"sample {path}: {node + 1} nodes")
    return table


def expect_objects(path, fps, membs, grid):
    """[(name, fp, m, [(x, y, value, u, w, z) per node])] expected."""
    rows, cols = map(int, grid.split("x"))
    tab = sample_table(path, grid)
    objs = []
    for fp in fps:
        for m in membs:
            verts = []
            for r in range(rows):
                for c in range(cols):
                    s = tab[(r, c, fp)]
                    verts.append((s["x"], s["y"], s[m], s["u"], s["w"],
                                  s.get("z")))
            objs.append((f"{fp}_{m}", fp, m, verts))
    return objs


def quads(rows, cols, base):
    return [(base + r * cols + c, base + (r + 1) * cols + c,
             base + (r + 1) * cols + c + 1, base + r * cols + c + 1)
            for r in range(rows - 1) for c in range(cols - 1)]


def parse_vtk(text):
    """Legacy ASCII POLYDATA: points, polygons, cell and point arrays."""
    tok = text.split("\n")
    check(tok[0] == "# vtk DataFile Version 3.0", "vtk: version line")
    check(len(tok[1]) < 256, "vtk: title under 256 characters")
    check(tok[2] == "ASCII" and tok[3] == "DATASET POLYDATA", "vtk: kind")
    words = " ".join(tok[4:]).split()
    pos = 0

    def take(k=1):
        nonlocal pos
        pos += k
        return words[pos - k:pos] if k > 1 else words[pos - 1]

    out = {"cell": {}, "point": {}}
    section = None
    while pos < len(words):
        kw = take()
        if kw == "POINTS":
            n, typ = int(take()), take()
            check(typ == "double", "vtk: point type")
            out["points"] = [tuple(take(3)) for _ in range(n)]
        elif kw == "POLYGONS":
            n, size = int(take()), int(take())
            polys = []
            for _ in range(n):
                k = int(take())
                polys.append(tuple(int(x) for x in take(k)))
            check(sum(len(p) + 1 for p in polys) == size, "vtk: POLYGONS size")
            out["polys"] = polys
        elif kw in ("CELL_DATA", "POINT_DATA"):
            section = "cell" if kw == "CELL_DATA" else "point"
            out[section + "_n"] = int(take())
        elif kw == "SCALARS":
            name, typ, comps = take(3)
            check(take(2) == ["LOOKUP_TABLE", "default"], "vtk: lookup table")
            out[section][name] = take(out[section + "_n"])
            if out[section + "_n"] == 1:
                out[section][name] = [out[section][name]]
        else:
            check(False, f"vtk: unexpected keyword {kw!r}")
            break
    return out


def parse_obj(text):
    """[(name, group, [vertex], [face])], face indices 1-based global."""
    objs, verts = [], []
    for ln in text.split("\n"):
        f = ln.split()
        if not f or f[0] == "#":
            continue
        if f[0] == "o":
            objs.append([f[1], None, [], []])
        elif f[0] == "g":
            objs[-1][1] = f[1]
        elif f[0] == "v":
            verts.append(tuple(f[1:]))
            objs[-1][2].append(tuple(f[1:]))
        elif f[0] == "f":
            objs[-1][3].append(tuple(int(x) for x in f[1:]))
        else:
            check(False, f"obj: unexpected line {ln!r}")
    return objs, verts


def test_export_case(tmp, path, grid, extra, fps, membs):
    rows, cols = map(int, grid.split("x"))
    exp = expect_objects(path, fps, membs, grid)
    per = rows * cols
    what = f"export {path} {grid} {extra}"

    # VTK, written with -o
    out = os.path.join(tmp, "mesh.vtk")
    rc, so, se = run("export", path, "--format", "vtk", "--grid", grid,
                     "-o", out, *extra)
    check(rc == 0 and so == "" and se == "", f"{what} vtk: {rc} {se!r}")
    v = parse_vtk(open(out).read())
    pts = [p for _, _, _, vs in exp for p in vs]
    check(v["points"] == [p[:3] for p in pts], f"{what} vtk: vertices")
    check(v["polys"] == [q for k in range(len(exp))
                         for q in quads(rows, cols, k * per)],
          f"{what} vtk: quads")
    nq = (rows - 1) * (cols - 1)
    check(v["cell"]["footprint_id"] == [str(FPS.index(fp)) for _, fp, _, _
                                        in exp for _ in range(nq)],
          f"{what} vtk: footprint_id")
    check(v["cell"]["membership_id"] == [str(MEMB.index(m)) for _, _, m, _
                                         in exp for _ in range(nq)],
          f"{what} vtk: membership_id")
    check(v["point"]["value"] == [p[2] for p in pts], f"{what} vtk: value")
    check(v["point"]["u"] == [p[3] for p in pts] and
          v["point"]["w"] == [p[4] for p in pts], f"{what} vtk: u, w")
    if pts[0][5] is not None:
        check(v["point"]["z"] == [p[5] for p in pts], f"{what} vtk: z")
    else:
        check("z" not in v["point"], f"{what} vtk: no z")

    # OBJ, on stdout
    rc, so, se = run("export", path, "--format", "obj", "--grid", grid,
                     *extra)
    check(rc == 0 and se == "", f"{what} obj: {rc} {se!r}")
    objs, verts = parse_obj(so)
    check([o[0] for o in objs] == [e[0] for e in exp] and
          all(o[0] == o[1] for o in objs), f"{what} obj: object names")
    for k, (o, e) in enumerate(zip(objs, exp)):
        check(o[2] == [p[:3] for p in e[3]], f"{what} obj {o[0]}: vertices")
        check(o[3] == quads(rows, cols, 1 + k * per),
              f"{what} obj {o[0]}: faces")
    check(len(verts) == len(pts), f"{what} obj: vertex count")

    # CSV
    rc, so, se = run("export", path, "--format", "csv", "--grid", grid,
                     *extra)
    lines = so.strip().split("\n")
    z = pts[0][5] is not None
    check(rc == 0 and lines[0] == "object,footprint,membership,r,c,u,w,x,y"
          + (",z" if z else "") + ",value", f"{what} csv header")
    want = []
    for name, fp, m, vs in exp:
        for idx, p in enumerate(vs):
            r, c = divmod(idx, cols)
            want.append(",".join([name, fp, m, str(r), str(c), p[3], p[4],
                                  p[0], p[1]] + ([p[5]] if z else [])
                                 + [p[2]]))
    check(lines[1:] == want, f"{what} csv rows")


def test_export(tmp):
    test_export_case(tmp, PAPER, "5x4", [], FPS, MEMB)
    test_export_case(tmp, PAPER, "3x6", ["--membership", "I", "--footprint",
                                         "RR,LR", "--footprint", "D"],
                     ["LR", "D", "RR"], ["I"])
    test_export_case(tmp, "examples/type1_4x3.csv", "4x4", [], ["D"], MEMB)
    test_export_case(tmp, "examples/z_3x3.csv", "3x3", ["--membership", "F"],
                     FPS, ["F"])
    rc, so, se = run("export", PAPER)
    check(rc == 1 and "export needs --format" in se, f"no format: {se!r}")
    rc, so, se = run("export", PAPER, "--format", "ply")
    check(rc == 1 and "--format 'ply'" in se, f"bad format: {se!r}")
    rc, so, se = run("export", PAPER, "--format", "obj", "--interval")
    check(rc == 1 and "--interval does not apply" in se,
          f"export --interval: {se!r}")
    rc, so, se = run("export", PAPER, "--format", "obj", "-o",
                     os.path.join(tmp, "no/dir/x.obj"))
    check(rc == 2 and "cannot create" in se, f"export unwritable: {se!r}")
    # Default grid 21x21, every footprint and membership.
    rc, so, _ = run("export", PAPER, "--format", "obj")
    check(so.count("\no ") == 21 and so.count("\nv ") == 21 * 21 * 21,
          "export default grid and objects")


def test_sample_footprint():
    full = sample_table(PAPER, "3x2")
    part = sample_table(PAPER, "3x2", ["--footprint", "RR,D"])
    check(sorted(part) == sorted(k for k in full if k[2] in ("D", "RR")),
          "sample --footprint keeps D and RR only")
    check(all(part[k] == full[k] for k in part), "sample --footprint rows")
    rc, out, _ = run("sample", PAPER, "--grid", "2x2", "--footprint", "D",
                     "--summary")
    fps = [ln.split(",")[2] for ln in out.strip().split("\n")[1:]]
    check(fps == ["D", "upper_min", "upper_max", "lower_min",
                  "lower_max"] * 4, f"sample --footprint --summary: {fps}")
    rc, _, se = run("sample", "examples/type1_4x3.csv", "--grid", "2x2",
                    "--footprint", "LL")
    check(rc == 2 and se == "examples/type1_4x3.csv: --footprint LL: not in "
          "this type-1 model (footprint D only)\n", f"type-1 footprint: {se!r}")
    rc, _, se = run("sample", PAPER, "--grid", "2x2", "--footprint", "")
    check(rc == 1 and "--footprint ''" in se, f"empty footprint: {se!r}")
    rc, _, se = run("eval", PAPER, "--at", "0,0", "--footprint", "D")
    check(rc == 1 and "--footprint does not apply to eval" in se,
          f"eval --footprint: {se!r}")


def main():
    with tempfile.TemporaryDirectory() as tmp:
        os.mkdir(os.path.join(tmp, "empty"))
        test_plot(tmp)
        test_figures(tmp)
        test_export(tmp)
    test_sample_footprint()
    for fig in FIGURES:
        check_png(fig, *((1000, 500) if "band" in fig else (900, 700)), f"committed figure {fig}")
    return R.finish()


if __name__ == "__main__":
    sys.exit(main())
