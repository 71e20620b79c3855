"""Du et al. 2018, Table 1, on the shipped cast: the range error of a constant surface sound speed.

For each of the paper's rows (towfish depth h and ray-traced distance S2), the ray joining a transducer at the
surface to a towfish at depth h and horizontal offset sqrt(S2^2 - h^2) is found through the cast's layers; its
travel time times the surface speed is the surface-speed range S1, and dS = S1 - S2. The paper's profile is not
published: the shipped cast (a synthetic northern South China Sea June profile, lost/host/usbl/data/scs_june.csv)
stands in, so the figures agree in kind, not digit for digit.

Run: .venv/bin/python benchmarks/usbl_table1.py
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import brentq

from lost.host.usbl.rays import trace_to_depth
from lost.host.usbl.scenario import shipped_cast_path
from lost.host.usbl.sound import SoundSpeedProfile, read_cast

PAPER_TABLE_1 = [(50.25, 66.12, 65.98, 0.14), (153.91, 202.05, 201.28, 0.77), (246.36, 323.55, 322.42, 1.13), (352.86, 465.62, 461.29, 4.33),
                 (456.35, 605.38, 596.75, 8.63), (548.51, 729.04, 717.03, 12.01), (651.38, 868.19, 851.45, 16.74),
                 (747.64, 998.13, 976.99, 21.14), (850.73, 1135.75, 1111.57, 24.18), (949.12, 1271.22, 1240.37, 30.85),
                 (1051.18, 1408.68, 1373.59, 35.09)]


def main() -> None:
    profile = SoundSpeedProfile.from_cast(read_cast(shipped_cast_path("scs_june")))
    surface = float(profile.speed_at(0.0))
    print(f"surface speed {surface:.2f} m/s")
    print("| h (m) | S2 (m) | paper S1 (m) | paper dS (m) | LOST S1 (m) | LOST dS (m) |")
    print("|---:|---:|---:|---:|---:|---:|")
    for depth, paper_s1, distance, paper_error in PAPER_TABLE_1:
        horizontal = np.sqrt(distance**2 - depth**2)
        angle = brentq(lambda a, d=depth, h=horizontal: trace_to_depth(profile, a, 0.0, d).horizontal_m - h, 0.0, 1.5)
        s1 = surface * trace_to_depth(profile, angle, 0.0, depth).time_s
        print(f"| {depth:.2f} | {distance:.2f} | {paper_s1:.2f} | {paper_error:.2f} | {s1:.2f} | {round(s1 - distance, 2) + 0.0:.2f} |")


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()  # --help, and no stray options
    main()
