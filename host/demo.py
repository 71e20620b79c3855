"""The built-in demo: cut a sonar patch from a synthetic sea floor and find it again.

Until the navigation pipeline lands this is what ``make demo`` runs: it shows the correlator recover
a noisy, offset patch on the paper's sizes (501 x 501 map, 10 x 10 patch, 10 m nodes).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from lost import model
from lost.host import correlate
from lost.host.terrain import synthetic_terrain


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.host.demo", description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2002, help="terrain and noise seed")
    parser.add_argument("--map", type=int, default=501, help="map side, nodes")
    parser.add_argument("--patch", type=int, default=10, help="patch side, nodes")
    parser.add_argument("--noise-m", type=float, default=0.5, help="sonar depth noise, metres (1 sigma)")
    parser.add_argument("--offset-m", type=float, default=7.3, help="unknown depth offset of the sonar, metres")
    parser.add_argument("--backend", default="software", help="correlator backend")
    args = parser.parse_args(argv)

    rng = np.random.default_rng(args.seed)
    floor_m = synthetic_terrain((args.map, args.map), seed=args.seed)
    lsb_m, offset_m = 0.1, float(np.round(floor_m.mean()))
    terrain = model.quantize(floor_m, lsb_m, offset_m=offset_m)
    true_i, true_j = (int(x) for x in rng.integers(0, args.map - args.patch + 1, size=2))
    sounding_m = floor_m[true_i : true_i + args.patch, true_j : true_j + args.patch]
    sounding_m = sounding_m + args.offset_m + rng.normal(0.0, args.noise_m, sounding_m.shape)
    patch = model.quantize(sounding_m, lsb_m, offset_m=offset_m)

    start = time.perf_counter()
    surface = correlate(terrain, patch, backend=args.backend)
    elapsed_ms = (time.perf_counter() - start) * 1e3
    fit = model.best_fit(surface, exclusion_radius=args.patch // 2)

    print(f"map {args.map} x {args.map}, patch {args.patch} x {args.patch}, 10 m nodes, {lsb_m} m depth step")
    print(f"sonar noise {args.noise_m} m (1 sigma), unknown depth offset {args.offset_m} m, seed {args.seed}")
    print(f"backend {args.backend!r}: surface of {surface.shape[0]} x {surface.shape[1]} in {elapsed_ms:.2f} ms")
    print(f"best fit   (i, j) = ({fit.i}, {fit.j})   V = {fit.value}")
    print(f"true       (i, j) = ({true_i}, {true_j})")
    if fit.runner_up is not None:
        ru = fit.runner_up
        print(f"runner-up  (i, j) = ({ru.i}, {ru.j})   V = {ru.value}   ratio {ru.value / max(fit.value, 1):.2f}")
    found = (fit.i, fit.j) == (true_i, true_j)
    print("found the true placement" if found else "MISSED the true placement")
    return 0 if found else 1


if __name__ == "__main__":
    raise SystemExit(main())
