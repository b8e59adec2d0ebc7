#!/usr/bin/python3
"""What can be checked here of the Zephyr module and the PlatformIO manifest
(neither SDK is installed): every file they list exists, they build exactly
the sources the Makefile builds (firmware_core/*.c, protocol/*.c), the
Kconfig options are the #ifndef options of firmware_core/it2n.h with the
same defaults and ranges, and zephyr/CMakeLists.txt passes each one on.
Also: docs/firmware.md quotes its example files verbatim and its options
table matches it2n.h.

usage: check_dropin.py   (from the repository root; exit 1 on any mismatch)
"""
import glob
import json
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
errors = []


def err(msg):
    errors.append(msg)


def read(rel):
    with open(os.path.join(ROOT, rel), encoding="utf-8") as f:
        return f.read()


def exists(rel):
    return os.path.exists(os.path.join(ROOT, rel))


# The sources the Makefile and CMakeLists.txt build: DIR/sources.txt.
MAKE_SOURCES = sorted(d + "/" + n for d in ("firmware_core", "protocol")
                      for n in read(d + "/sources.txt").split())
CORE_SOURCES = [s for s in MAKE_SOURCES if s.startswith("firmware_core/")]
VERSION = read("VERSION").strip()


# ---- it2n.h options --------------------------------------------------------
def header_options():
    """{name: (default text, lo, hi)} of every `#ifndef X / #define X ...`."""
    text = read("firmware_core/it2n.h")
    opts = {}
    for m in re.finditer(r"^#ifndef (IT2N_[A-Z0-9_]+)\n#define \1(\([a-z]\))? *(.*)$", text, re.M):
        name, default = m.group(1), m.group(3).strip()
        if default == "":          # include guard
            continue
        opts[name] = [default, None, None]
    for line in re.findall(r"^#if (.*)$", text, re.M):
        for name, lo in re.findall(r"(IT2N_[A-Z0-9_]+) < (\d+)", line):
            if name in opts:
                opts[name][1] = int(lo)
        for name, hi in re.findall(r"(IT2N_[A-Z0-9_]+) > (\d+)", line):
            if name in opts:
                opts[name][2] = int(hi)
    return opts


def kconfig_options():
    """{name: {type, default, range}} of zephyr/Kconfig."""
    text = read("zephyr/Kconfig")
    out, cur = {}, None
    for line in text.splitlines():
        m = re.match(r"^(?:menu)?config (\w+)$", line)
        if m:
            cur = out.setdefault(m.group(1), {})
            continue
        if cur is None:
            continue
        s = line.strip()
        m = re.match(r"^(bool|int|string|hex)\b", s)
        if m:
            cur["type"] = m.group(1)
        m = re.match(r"^default (\S+)$", s)
        if m:
            cur["default"] = m.group(1)
        m = re.match(r"^range (\S+) (\S+)$", s)
        if m:
            cur["range"] = (int(m.group(1)), int(m.group(2)))
    return out


def check_kconfig():
    hdr = header_options()
    kc = kconfig_options()
    # IT2N enables the module, IT2N_PROTOCOL the protocol library: not it2n.h options.
    kc_opts = {k: v for k, v in kc.items() if k not in ("IT2N", "IT2N_PROTOCOL")}
    if "IT2N" not in kc:
        err("zephyr/Kconfig: no IT2N symbol to enable the module")
    for name in sorted(set(hdr) - set(kc_opts)):
        err(f"zephyr/Kconfig: it2n.h option {name} has no Kconfig symbol")
    for name in sorted(set(kc_opts) - set(hdr)):
        err(f"zephyr/Kconfig: {name} is not an option of it2n.h")
    cmake = read("zephyr/CMakeLists.txt")
    for name in sorted(set(hdr) & set(kc_opts)):
        default, lo, hi = hdr[name]
        k = kc_opts[name]
        if name == "IT2N_ASSERT":  # a macro: off ((void)0) by default
            want_type, want_default = "bool", "n"
        elif default in ("0", "1") and k.get("type") == "bool":
            want_type, want_default = "bool", "y" if default == "1" else "n"
        else:
            want_type, want_default = "int", default
        if k.get("type") != want_type:
            err(f"zephyr/Kconfig: {name} is {k.get('type')}, expected {want_type}")
        if k.get("default") != want_default:
            err(f"zephyr/Kconfig: {name} default {k.get('default')}, it2n.h says {default} ({want_default})")
        if want_type == "int":
            rng = k.get("range")
            if rng is None:
                err(f"zephyr/Kconfig: {name} has no range")
            else:
                if lo is not None and rng[0] != lo:
                    err(f"zephyr/Kconfig: {name} range starts at {rng[0]}, it2n.h at {lo}")
                if hi is not None and rng[1] != hi:
                    err(f"zephyr/Kconfig: {name} range ends at {rng[1]}, it2n.h at {hi}")
        if f"CONFIG_{name}" not in cmake:
            err(f"zephyr/CMakeLists.txt: CONFIG_{name} not passed on")
        if name != "IT2N_ASSERT" and f"#define {name} " not in cmake:
            err(f"zephyr/CMakeLists.txt: generated header does not #define {name}")
    print(f"check_dropin: Kconfig: {len(hdr)} options of it2n.h ({', '.join(sorted(hdr))}) match")


# ---- zephyr module -----------------------------------------------------------
def check_zephyr():
    mod = read("zephyr/module.yml")
    cm = re.search(r"^\s+cmake:\s*(\S+)\s*$", mod, re.M)
    kc = re.search(r"^\s+kconfig:\s*(\S+)\s*$", mod, re.M)
    if not cm or not exists(os.path.join(cm.group(1), "CMakeLists.txt")):
        err("zephyr/module.yml: build.cmake does not name a directory with a CMakeLists.txt")
    if not kc or not exists(kc.group(1)):
        err("zephyr/module.yml: build.kconfig does not name an existing file")
    cmake = read("zephyr/CMakeLists.txt")
    listed = re.findall(r"\$\{IT2N_ROOT\}/([\w/.-]+)", cmake)
    for rel in listed:
        if not exists(rel):
            err(f"zephyr/CMakeLists.txt: {rel} does not exist")
    # a listed DIR/sources.txt stands for the sources it names
    srcs = sorted([r for r in listed if r.endswith(".c")] +
                  [os.path.dirname(r) + "/" + n for r in listed if r.endswith("/sources.txt") and exists(r)
                   for n in read(r).split()])
    if srcs != MAKE_SOURCES:
        err("zephyr/CMakeLists.txt: sources differ from the Makefile's: "
            f"missing {sorted(set(MAKE_SOURCES) - set(srcs))}, extra {sorted(set(srcs) - set(MAKE_SOURCES))}")
    print(f"check_dropin: zephyr: module.yml, {len(listed)} listed paths exist, sources = firmware_core/*.c + protocol/*.c")


# ---- PlatformIO ----------------------------------------------------------------
def pio_filter(filters, src_dir):
    """PlatformIO srcFilter semantics, enough for +<glob> / -<glob>: a glob
    relative to srcDir; a directory it matches stands for all its files."""
    base = os.path.join(ROOT, src_dir)
    selected = set()
    for f in filters:
        m = re.fullmatch(r"([+-])<(.+)>", f)
        if not m:
            err(f"library.json: cannot read srcFilter entry {f!r}")
            continue
        hits = set()
        for p in glob.glob(m.group(2), root_dir=base, recursive=True):
            full = os.path.join(base, p)
            if os.path.isdir(full):
                hits |= {os.path.relpath(q, base)
                         for q in glob.glob(os.path.join(full, "**", "*"), recursive=True)
                         if os.path.isfile(q)}
            else:
                hits.add(os.path.normpath(p))
        if m.group(1) == "+":
            if not hits:
                err(f"library.json: srcFilter {f} matches no file")
            selected |= hits
        else:
            selected -= hits
    return sorted(os.path.normpath(os.path.join(src_dir, p)) for p in selected if p.endswith(".c"))


def check_pio():
    lib = json.loads(read("library.json"))
    if lib.get("name") != "it2n":
        err("library.json: name is not it2n")
    if lib.get("version") != VERSION:
        err(f"library.json: version {lib.get('version')}, VERSION says {VERSION}")
    b = lib.get("build", {})
    src_dir = b.get("srcDir", "src")
    if not os.path.isdir(os.path.join(ROOT, src_dir)):
        err(f"library.json: srcDir {src_dir} does not exist")
    if not os.path.isdir(os.path.join(ROOT, b.get("includeDir", "include"))):
        err(f"library.json: includeDir {b.get('includeDir')} does not exist")
    incs = [b.get("includeDir", "include")]
    for fl in b.get("flags", []):
        m = re.fullmatch(r"-I ?(\S+)", fl)
        if m:
            incs.append(m.group(1))
            if not os.path.isdir(os.path.join(ROOT, m.group(1))):
                err(f"library.json: include directory {m.group(1)} does not exist")
    for h in lib.get("headers", []):
        if not any(exists(os.path.join(d, h)) for d in incs):
            err(f"library.json: header {h} is in none of {incs}")
    srcs = pio_filter(b.get("srcFilter", ["+<*>"]), src_dir)
    if srcs != MAKE_SOURCES:
        err("library.json: sources differ from the Makefile's: "
            f"missing {sorted(set(MAKE_SOURCES) - set(srcs))}, extra {sorted(set(srcs) - set(MAKE_SOURCES))}")
    for pat in lib.get("export", {}).get("include", []):
        if not glob.glob(os.path.join(ROOT, pat)):
            err(f"library.json: export pattern {pat} matches no file")
    print(f"check_dropin: library.json: version {VERSION}, {len(incs)} include dirs, {len(srcs)} sources = Makefile's, exports exist")


# ---- docs/firmware.md quotes ------------------------------------------------------
QUOTE = re.compile(r"<!-- file:([\w/.-]+) -->\n```[a-z]*\n(.*?)```\n<!-- /file -->", re.S)


def check_doc_quotes():
    doc = read("docs/firmware.md")
    n = 0
    for m in QUOTE.finditer(doc):
        rel, body = m.group(1), m.group(2)
        n += 1
        if not exists(rel):
            err(f"docs/firmware.md: quoted file {rel} does not exist")
        elif read(rel) != body:
            err(f"docs/firmware.md: the quote of {rel} differs from the file (copy the file into the doc)")
    if n == 0:
        err("docs/firmware.md: no <!-- file:... --> quote found")
    print(f"check_dropin: docs/firmware.md: {n} quoted file(s) verbatim")


def check_doc_options():
    """The options table of docs/firmware.md: every it2n.h option, its default."""
    hdr = header_options()
    rows = dict(re.findall(r"^\| `(IT2N_[A-Z0-9_]+)` \| `?([^|`]+?)`? \|", read("docs/firmware.md"), re.M))
    for name in sorted(set(hdr) - set(rows)):
        err(f"docs/firmware.md: option {name} missing from the options table")
    for name in sorted(set(rows) - set(hdr)):
        err(f"docs/firmware.md: options table lists {name}, not an option of it2n.h")
    for name in sorted(set(rows) & set(hdr)):
        if rows[name] != hdr[name][0]:
            err(f"docs/firmware.md: {name} default {rows[name]}, it2n.h says {hdr[name][0]}")
    # Ranges quoted in the meaning column: "(lo..hi)" or "(≥ lo)".
    for name, meaning in re.findall(r"^\| `(IT2N_[A-Z0-9_]+)` \| [^|]+ \| (.*)\|$", read("docs/firmware.md"), re.M):
        if name not in hdr:
            continue
        _, lo, hi = hdr[name]
        m = re.search(r"\((\d+)\.\.(\d+)\)|\(≥ (\d+)\)", meaning)
        doc = (None, None) if not m else \
            (int(m.group(1)), int(m.group(2))) if m.group(1) else (int(m.group(3)), None)
        if doc != (lo, hi):
            err(f"docs/firmware.md: {name} range {doc}, it2n.h says {(lo, hi)}")
    print(f"check_dropin: docs/firmware.md: options table = it2n.h ({len(rows)} options, defaults, ranges)")


def main():
    check_kconfig()
    check_zephyr()
    check_pio()
    if exists("docs/firmware.md"):
        check_doc_quotes()
        check_doc_options()
    else:
        err("docs/firmware.md missing")
    for e in errors:
        print("check_dropin: " + e, file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
