#!/usr/bin/python3
"""Worst-case stack of the instrument firmware (examples/firmware/), an
upper bound from GCC's call graphs (-fstack-usage -fcallgraph-info=su,
one .ci file per object):

  worst(f) = frame(f) + max over callees of worst(callee)

over the functions linked into the image (arm-none-eabi-nm). A call through
a function pointer (the link's callbacks, the stream's write) may reach any
linked function whose address is taken, approximated from above by every
linked function that no one calls directly (the callbacks, and entry points
of unused paths): its worst case is the largest of theirs. Interrupts: the
SysTick and UART0 handlers run at the same (reset) priority, so they do not
preempt each other; one of them (the deeper) can interrupt the deepest point
of main, with the 32-byte exception frame of a Cortex-M3 without FPU plus 4
bytes of alignment. Leaf helpers outside the call graphs (memcpy, memset,
libgcc's 64-bit division) are counted as 64 bytes each call chain (they use
at most a few registers pushed; '+ext').

usage: fw_stack.py ELF CI_FILE...   -> JSON on stdout
Exit 1 on recursion, unbounded dynamic frames or no frame information, each
said on stderr as "fw_stack: FAIL: ..." (tests/lib's Report).
"""
import json
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "qemu"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lib"))
from stack_report import parse  # noqa: E402  (the .ci parser of make size)
from it2ntest import report  # noqa: E402

ENTRY = "fw_reset_handler"
ISRS = ("fw_systick_isr", "fw_uart0_rx_isr", "fw_fault_handler")
EXC_FRAME = 32 + 4
EXT = 64


def main():
    elf, cis = sys.argv[1], sys.argv[2:]
    R = report.Report("fw_stack", quiet_ok=True)
    nm = subprocess.run(["arm-none-eabi-nm", elf], check=True, capture_output=True, text=True).stdout
    linked = {l.split()[2] for l in nm.splitlines() if len(l.split()) == 3 and l.split()[1] in "tTwW"}
    frames, edges = parse(cis)
    if not frames:
        R.fail("no frame information in %d .ci file(s)" % len(cis))
        return R.finish(summary=False)
    frames = {k: v for k, v in frames.items() if k[1].rsplit(":", 1)[-1] in linked}
    by_name = {}
    for key in frames:
        by_name.setdefault(key[1], []).append(key)

    def resolve(path, name):
        if (path, name) in frames:
            return (path, name)
        c = by_name.get(name)
        return c[0] if c else None

    called = set()
    for key, cs in edges.items():
        if key in frames:
            for c in cs:
                r = resolve(key[0], c)
                if r:
                    called.add(r)
    roots = [k for k in frames if k not in called and k[1] != ENTRY and k[1] not in ISRS]
    memo, problems = {}, set()

    def worst(key, stack):
        if key in memo:
            return memo[key]
        if key in stack:
            problems.add("recursion through " + key[1])
            return (0, [key[1] + " (recursion)"])
        size, kind = frames[key]
        if "dynamic" in kind and "bounded" not in kind:
            problems.add("unbounded dynamic frame in " + key[1])
        best = (0, [])
        for c in sorted(edges.get(key, ())):
            if c == "__indirect_call":
                subs = [worst(r, stack | {key}) for r in roots if r != key]
                sub = max(subs, key=lambda s: s[0]) if subs else (0, [])
                sub = (sub[0], ["(via pointer) " + sub[1][0]] + sub[1][1:] if sub[1] else [])
            else:
                r = resolve(key[0], c)
                sub = (EXT, [c + " (ext)"]) if r is None else worst(r, stack | {key})
            if sub[0] > best[0]:
                best = sub
        res = (size + best[0], [key[1]] + best[1])
        memo[key] = res
        return res

    e = resolve("", ENTRY)
    if e is None:
        R.fail("no frame information for " + ENTRY)
        return R.finish(summary=False)
    main_w = worst(e, frozenset())
    isr = {}
    for n in ISRS:
        k = resolve("", n)
        if k:
            isr[n] = worst(k, frozenset())
    isr_max = max(isr.values(), key=lambda s: s[0]) if isr else (0, [])
    total = main_w[0] + isr_max[0] + EXC_FRAME
    out = {"method": "static: GCC -fstack-usage -fcallgraph-info=su call graphs of the linked functions, "
                     "indirect calls bounded by every root function, one interrupt (the deepest) on top "
                     "with a %d-byte exception frame, %d bytes per external leaf helper" % (EXC_FRAME, EXT),
           "worst_case_bytes": total,
           "main_bytes": main_w[0], "main_chain": main_w[1][:12],
           "interrupt_bytes": isr_max[0] + EXC_FRAME, "interrupt_chain": isr_max[1][:6],
           "isrs": {n: v[0] for n, v in isr.items()},
           "problems": sorted(problems)}
    print(json.dumps(out, indent=2))
    for p in sorted(problems):
        R.fail(p)
    if not problems:
        R.ok("worst case bounded: %d bytes" % total)
    return R.finish(summary=False)


if __name__ == "__main__":
    sys.exit(main())
