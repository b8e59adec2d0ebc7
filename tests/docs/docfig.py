#!/usr/bin/python3
"""Figures in README.md and docs/*.md that come from the build: each lives
between `<!-- fig:NAME -->` and `<!-- /fig:NAME -->` and is the verbatim
output of one command (below), in a fenced block.

usage: docfig.py --write   regenerate every block in place
       docfig.py --check [FILE...]  exit 1 with a diff if a committed block
                           differs (make test: a figure in the docs cannot
                           drift); FILE: other files than README.md and docs/

A figure whose name starts with "conf-keys-" is markdown, not a fenced
block: the configuration reference of one section, as `it2nd
--config-keys=markdown` prints it from daemon/conf_schema.c.
"""
import difflib
import glob
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BUILD = os.environ.get("BUILD", "build")


def run(cmd):
    out = subprocess.run(cmd, shell=True, cwd=ROOT, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    if out.returncode != 0:
        sys.stderr.write(out.stdout + out.stderr)
        raise SystemExit(f"docfig.py: command failed: {cmd}")
    return out.stdout


def grep(cmd, prefix):
    return "".join(l[2:] if l.startswith("  ") else l
                   for l in run(cmd).splitlines(keepends=True) if l.lstrip().startswith(prefix))


_SIZE = []


def make_size():
    if not _SIZE:
        _SIZE.append(run("make -s --no-print-directory size"))
    return _SIZE[0]


def size_section(first, last=None, keep=None):
    """Lines of `make size` from the one starting with `first` up to (not
    including) the next one starting with `last`, optionally filtered."""
    out, on = [], False
    for line in make_size().splitlines(keepends=True):
        if line.startswith(first):
            on = True
        elif on and last is not None and line.startswith(last):
            on = False
        if on and (keep is None or re.search(keep, line)):
            out.append(line)
    return "".join(out).strip("\n") + "\n"


STACK_KEEP = (r"^Worst-case|^  function|it2n_(model_solve|model_update|eval|deriv|sample|"
              r"locate|dataset_check|link_pump|proto_selftest|bspline_solve|bspline_eval) ")

def firmware_figures():
    """The instrument firmware's figures, from the committed bench/firmware.json
    (written by `make bench-firmware`)."""
    import json
    with open(os.path.join(ROOT, "bench", "firmware.json"), encoding="utf-8") as f:
        fw = json.load(f)
    img, parts, st = fw["image"], fw["parts_from_map"], fw["stack"]
    runs = fw["upload_over_emulated_uart"]
    out = ["%s (bench/firmware.json)" % fw["target"],
           "  whole image: flash %d bytes, static RAM %d bytes (stack reserved: %d)"
           % (img["flash_bytes"], img["static_ram_bytes"], img["stack_reserved_bytes"]),
           "  %-14s %8s %8s" % ("part", "flash", "RAM")]
    for name in ("core", "protocol", "driver", "application", "libc+libgcc"):
        if name in parts:
            out.append("  %-14s %8d %8d" % (name, parts[name]["flash"], parts[name]["ram"]))
    every = list(runs.values()) + [r for rd in fw.get("upload_rounds", []) for r in rd.values()]
    hw = max((r.get("stack_high_water_bytes") or 0) for r in every) if every else 0
    out.append("  stack: worst case %d bytes (static bound: main %d + interrupt %d), high-water %d bytes (measured)"
               % (st["worst_case_bytes"], st["main_bytes"], st["interrupt_bytes"], hw))
    for name in ("direct", "lossy"):
        if name in runs:
            r = runs[name]
            out.append("  upload %-6s %5d ms, %d entries in %d PUT frames, %d retransmissions (byte drop %d ppm)"
                       % (name, r["upload_ms"], r["entries"], r["put_frames"], r["retransmissions"],
                          r["byte_drop_ppm"]))
    return "\n".join(out) + "\n"


_CONF_KEYS = []


def conf_keys(section):
    """The `### [section]` heading and key table of it2nd --config-keys=markdown."""
    if not _CONF_KEYS:
        _CONF_KEYS.append(run(f"{BUILD}/host/it2nd --config-keys=markdown"))
    for block in _CONF_KEYS[0].split("\n### "):
        block = block if block.startswith("### ") else "### " + block
        if block.startswith("### `[%s" % section):
            return block.rstrip("\n") + "\n"
    raise SystemExit(f"docfig.py: it2nd --config-keys has no section '{section}'")


def fleet_figures():
    """The fleet benchmark's figures, from the committed bench/fleet.json
    (written by `make bench-fleet`, tests/sparkplug/spb_fleet.py)."""
    import json
    with open(os.path.join(ROOT, "bench", "fleet.json"), encoding="utf-8") as f:
        fl = json.load(f)
    c = fl["conditions"]
    out = ["bench/fleet.json (%s, %d CPUs, load %.1f)" % (c["utc"], c["cpus"], c["loadavg_1min"])]
    for r in fl["rows"]:
        v = r["value"]
        tgt = "" if r["target"] is None else "   target <= %g: %s" % (r["target"], "met" if r["met"] else "MISSED")
        out.append("  %-78s %9s %s%s" % (r["name"], ("%g" % v), r["unit"], tgt))
    return "\n".join(out) + "\n"


# name -> function returning the block's text
FIGURES = {
    "size-flash": lambda: size_section("== Flash", "Worst-case"),
    "size-stack": lambda: size_section("Worst-case", "== sizeof", STACK_KEEP),
    "size-structs": lambda: size_section("== sizeof"),
    "accuracy": lambda: grep(f"{BUILD}/tests/core/test_accuracy", "[accuracy]"),
    "operations": lambda: grep(f"{BUILD}/tests/core/test_operations", "[operations]"),
    "bspline": lambda: grep(f"{BUILD}/tests/core/test_bspline", "[bspline]"),
    "daemon-memory": lambda: grep(f"{BUILD}/tests/daemon/test_models", "[memory]"),
    "fw-figures": firmware_figures,
    "fleet": fleet_figures,
    "fw-budget": lambda: run("/usr/bin/python3 tests/firmware/fw_budget.py"),
    "fw-timing": lambda: run("/usr/bin/python3 tests/firmware/fw_budget.py --timing"),
}
for _sec in ("daemon", "modbus", "listen", "rtu", "model", "link", "sparkplug", "metrics"):
    FIGURES["conf-keys-" + _sec] = (lambda s: lambda: conf_keys(s))(_sec)

BLOCK = re.compile(r"(<!-- fig:([a-z0-9-]+) -->\n)(.*?)(<!-- /fig:\2 -->)", re.S)


def render(name):
    if name not in FIGURES:
        raise SystemExit(f"docfig.py: unknown figure '{name}'")
    if name.startswith("conf-keys-"):
        return FIGURES[name]()
    return "```\n" + FIGURES[name]().rstrip("\n") + "\n```\n"


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else "--check"
    cache, bad = {}, False
    files = [os.path.abspath(f) for f in sys.argv[2:]] or \
        [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md")))
    for path in files:
        with open(path, encoding="utf-8") as f:
            text = f.read()

        def sub(m):
            name = m.group(2)
            if name not in cache:
                cache[name] = render(name)
            return m.group(1) + cache[name] + m.group(4)

        new = BLOCK.sub(sub, text)
        if new == text:
            continue
        rel = os.path.relpath(path, ROOT)
        if mode == "--write":
            with open(path, "w", encoding="utf-8") as f:
                f.write(new)
            print(f"docfig.py: updated {rel}")
        else:
            bad = True
            sys.stdout.writelines(difflib.unified_diff(
                text.splitlines(keepends=True), new.splitlines(keepends=True),
                f"{rel} (committed)", f"{rel} (from the build)"))
    if bad:
        print("docfig.py: figures in the docs are stale: run 'make docs-figures'", file=sys.stderr)
        return 1
    print(f"docfig.py: {len(cache)} generated figure(s) current" if mode != "--write"
          else f"docfig.py: {len(cache)} figure(s) written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
