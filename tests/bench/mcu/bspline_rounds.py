#!/usr/bin/python3
"""x86-64 B-spline solve times in interleaved rounds (issue 22): reads
`bench_bspline --rounds MAX` round by round (every round solves each grid
once, the order reversed on odd rounds) and stops once the 95 % intervals
of the type-2 256x256 solve's CPU time against its 50 ms goal and against
the type-1 256x256 solve of the same rounds lie within +-5 %
(results.until_precise: at least MIN_ROUNDS rounds), or after MAX rounds.

usage: bspline_rounds.py BENCH_BSPLINE MAX_ROUNDS > LOG

LOG: "R host.solve_ms.KEY t1 t2 ..." (wall clock) and
"R host.solve_cpu_ms.KEY t1 t2 ..." (process CPU time), ms per solve, one
per round, paired by position; "R host.loadavg 1m 5m 15m" (at the end of
the rounds), "R host.rounds N" and "R host.max_rounds_reached 0|1", read
by bspline_results.py host.
"""
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from results import until_precise  # noqa: E402

GOAL_MS = 50.0  # issue 21: the 256x256 type-2 x,y,z solve within 50 ms
MIN_ROUNDS = 5  # a 95 % interval from fewer reads too much into chance


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    exe, max_rounds = sys.argv[1], int(sys.argv[2])
    p = subprocess.Popen([exe, "--rounds", str(max_rounds)], stdout=subprocess.PIPE, text=True)
    wall, cpu = {}, {}  # key -> [ms per round]

    def one_round(_r):
        text = p.stdout.readline()
        parts = text.split()
        if parts[:2] != ["R", "host.round"] or (len(parts) - 2) % 3:
            raise SystemExit(f"bspline_rounds.py: {exe} ended early or printed {text!r} (exit {p.poll()})")
        for i in range(2, len(parts), 3):
            wall.setdefault(parts[i], []).append(float(parts[i + 1]))
            cpu.setdefault(parts[i], []).append(float(parts[i + 2]))

    def pairs():
        t2 = cpu.get("t2xyz256", [])
        return [(t2, [GOAL_MS] * len(t2)), (t2, cpu.get("t1xyz256", []))]

    rounds, capped = until_precise(one_round, pairs, max_rounds, min_rounds=MIN_ROUNDS)
    p.terminate()  # it would go on to max_rounds
    p.wait()
    for name, d in (("solve_ms", wall), ("solve_cpu_ms", cpu)):
        for key, v in d.items():
            print(f"R host.{name}.{key} " + " ".join(f"{x:.3f}" for x in v))
    print("R host.loadavg " + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    print(f"R host.rounds {rounds}")
    print(f"R host.max_rounds_reached {int(capped)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
