#!/usr/bin/env python3
"""Write a random but valid type-2 data set CSV: degrees N x M, footprints
nested on x and y, memberships in [0, 1] (4 decimals).
usage: gen_dataset.py N M SEED [COORD_DECIMALS]  (2 = exact through the Modbus
upload registers at coord_scale 100)"""
import random
import sys

n, m, seed = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
dec = int(sys.argv[4]) if len(sys.argv) > 4 else 4
rnd = random.Random(seed)
fps = ["LL", "LR", "L", "D", "R", "RL", "RR"]
print("i,j,footprint,x,y,T,I,F")
for i in range(n + 1):
    for j in range(m + 1):
        x, y = i * 10 + rnd.uniform(-3, 3), j * 10 + rnd.uniform(-3, 3)
        t, ii, f = (round(rnd.random(), 4) for _ in range(3))
        spread = [0.0]
        for _ in range(3):
            spread.append(spread[-1] + rnd.uniform(0.1, 1.0))  # >= 0.1: nesting survives rounding
        offs = [-spread[3], -spread[2], -spread[1], 0.0, spread[1], spread[2], spread[3]]
        for fp, d in zip(fps, offs):
            print("%d,%d,%s,%.*f,%.*f,%s,%s,%s" % (i, j, fp, dec, x + d, dec, y + d, t, ii, f))
