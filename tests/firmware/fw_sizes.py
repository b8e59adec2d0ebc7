#!/usr/bin/python3
"""Flash and RAM of the firmware image per part, from the linker map.
usage: fw_sizes.py MAP  -> JSON object on stdout"""
import json
import re
import sys

parts = {}
def part_of(path):
    if "firmware_core/" in path:
        return "core"
    if "protocol/" in path:
        return "protocol"
    if re.search(r"examples/firmware/(board|startup)\.o|tests/qemu/semihost\.o", path):
        return "driver"
    if "examples/" in path:
        return "application"
    return "libc+libgcc"

out_sec = None
started = False
pending = None
with open(sys.argv[1]) as f:
    for line in f:
        if line.startswith("Linker script and memory map"):
            started = True
            continue
        if not started:
            continue
        m = re.match(r"^(\.[A-Za-z_.]+)\s", line)
        if m and not line.startswith(" "):
            out_sec = m.group(1)
            continue
        m = re.match(r"^ (\.\S+|COMMON)\s*$", line)
        if m:
            pending = m.group(1)
            continue
        m = re.match(r"^ (\.\S+|COMMON)?\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+\.o\)?|\S+\.a\(\S+\))\s*$", line)
        if m and (m.group(1) or pending):
            size = int(m.group(3), 16)
            pending = None
            if size == 0 or out_sec is None:
                continue
            p = part_of(m.group(4))
            d = parts.setdefault(p, {"flash": 0, "ram": 0})
            if out_sec in (".text", ".ARM.exidx", ".rodata"):
                d["flash"] += size
            elif out_sec == ".data":
                d["flash"] += size
                d["ram"] += size
            elif out_sec == ".bss":
                d["ram"] += size
        else:
            pending = None
total = {"flash": sum(d["flash"] for d in parts.values()),
         "ram": sum(d["ram"] for d in parts.values())}
print(json.dumps({"parts": parts, "total_static": total}, indent=2, sort_keys=True))
