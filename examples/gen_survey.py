#!/usr/bin/env python3
"""Generate examples/survey_64x64.csv: a 64 x 64 uncertain bathymetry survey
for the B-spline kind (it2n --kind bspline).

A swath over a 630 m x 630 m area, one sounding every 10 m with a small
position error; depth z is a sloping sea floor with a mound and a channel.
The seven footprints LL..RR carry the positional and depth uncertainty of
each sounding (wider where the beam is far from the ship's track, which runs
along j = 32), and T, I, F say how much each sounding is trusted: true
(T) near the track, indeterminate (I) in the outer beams, false (F) where
the returns are weak. Exact arithmetic (fractions, integer noise) only, so
the output is the same byte for byte on every machine:

    /usr/bin/python3 examples/gen_survey.py > examples/survey_64x64.csv
"""
from fractions import Fraction as Fr

N = 64
FPS = ["LL", "LR", "L", "D", "R", "RL", "RR"]


def noise(seed):
    """Deterministic value in [-1, 1) from an integer LCG step."""
    x = (seed * 6364136223846793005 + 1442695040888963407) % (1 << 64)
    x = (x ^ (x >> 29)) * 0xBF58476D1CE4E5B9 % (1 << 64)
    return Fr(x >> 40, 1 << 23) - 1


def fmt(v, decimals):
    """v rounded to `decimals` places (ties away from zero), as text."""
    scale = 10 ** decimals
    q = abs(v) * scale
    k = int(q + Fr(1, 2))
    sign = "-" if v < 0 and k != 0 else ""
    s = str(k).rjust(decimals + 1, "0")
    return sign + s[:-decimals] + "." + s[-decimals:]


def depth(x, y):
    """Sea floor (m, negative down): slope, a mound, a channel."""
    slope = -30 - Fr(x, 40)
    dx, dy = x - 250, y - 380
    mound = Fr(12) / (1 + (dx * dx + dy * dy) / Fr(6000))
    cy = y - 150 - Fr(x, 5)
    channel = -Fr(8) / (1 + cy * cy / Fr(900))
    return slope + mound + channel


def main():
    print("# 64x64 uncertain bathymetry survey (examples/gen_survey.py)")
    print("# x, y, z in metres; track along j = 32; see docs/numerics.md")
    print("i,j,footprint,x,y,z,T,I,F")
    for i in range(N):
        for j in range(N):
            seed = i * N + j
            x = 10 * i + Fr(1, 2) * noise(3 * seed)
            y = 10 * j + Fr(1, 2) * noise(3 * seed + 1)
            z = depth(x, y) + Fr(1, 20) * noise(3 * seed + 2)
            off = Fr(abs(j - 32), 32)          # 0 on the track, 1 at the edge
            dxy = Fr(1, 10) + Fr(3, 10) * off  # position spread per step (m)
            dz = Fr(1, 20) + Fr(1, 5) * off    # depth spread per step (m)
            t = Fr(9, 10) - Fr(1, 2) * off * off
            ind = Fr(1, 20) + Fr(3, 10) * off
            f = Fr(1, 40) + Fr(1, 10) * off * off + Fr(1, 50) * (1 + noise(7 * seed))
            for k, fp in enumerate(FPS):
                s = k - 3
                # outer footprints: wider positions, lower trust
                tt = t - Fr(abs(s), 40)
                ii = ind + Fr(abs(s), 60)
                ff = f + Fr(abs(s), 80)
                print(",".join([str(i), str(j), fp, fmt(x + s * dxy, 3),
                                fmt(y + s * dxy, 3), fmt(z + s * dz, 3),
                                fmt(tt, 3), fmt(ii, 3), fmt(ff, 3)]))


if __name__ == "__main__":
    main()
