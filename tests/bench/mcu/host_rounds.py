#!/usr/bin/python3
"""x86-64 query times of it2n, double and float in interleaved rounds
(issue 22): reads `bench_host time MAX` round by round and stops once the
it2n/double ratio's 95 % interval lies within +-5 % on every data set
(results.until_precise: at least 3 rounds), or after MAX rounds.

usage: host_rounds.py BENCH_HOST MAX_ROUNDS [quick] > LOG

LOG: "R SET.x86.IMPL_ns t1 t2 ..." (ns per query, one per round, paired by
position), "R x86.loadavg 1m 5m 15m" (at the end of the rounds),
"R x86.rounds N" and "R x86.max_rounds_reached 0|1", read by results.py.
"""
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from results import until_precise  # noqa: E402

IMPLS = ["it2n", "double", "float"]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    host, max_rounds = sys.argv[1], int(sys.argv[2])
    p = subprocess.Popen([host, "time", str(max_rounds)] + sys.argv[3:], stdout=subprocess.PIPE, text=True)
    times = {}  # set -> impl -> [ns per round]

    def line():
        text = p.stdout.readline()
        if not text.startswith("R x86."):
            raise SystemExit(f"host_rounds.py: {host} ended early or printed {text!r} (exit {p.poll()})")
        return text.split()

    nsets = int(line()[2])

    def one_round(_r):
        for _ in range(nsets):
            parts = line()
            s = parts[1][len("x86.round."):]
            for impl, v in zip(IMPLS, parts[2:]):
                times.setdefault(s, {}).setdefault(impl, []).append(float(v))

    def pairs():
        return [(t["it2n"], t["double"]) for t in times.values()]

    rounds, capped = until_precise(one_round, pairs, max_rounds)
    p.terminate()  # it would go on to max_rounds
    p.wait()
    for s, t in times.items():
        for impl in IMPLS:
            print(f"R {s}.x86.{impl}_ns " + " ".join(f"{v:.3f}" for v in t[impl]))
    print("R x86.loadavg " + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    print(f"R x86.rounds {rounds}")
    print(f"R x86.max_rounds_reached {int(capped)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
