"""The planner's speed: `lost plan`'s bound over a 2000 x 2000 map (the goal: under a minute here).

python benchmarks/plan_speed.py [--size 2000] [--repeats 3]: prints the median, minimum and maximum seconds of
``accuracy_grid`` and of ``lookalike_grid`` (600 m search) on a seeded von Karman floor at 10 m, and of the whole
command (reading the map, both grids, the NetCDF, the picture, and the prediction along the map's diagonal, 28 km:
the held error's bound and the update-by-update mixture).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lost.host.grid import Grid
from lost.host.io import write_npz
from lost.host.plan import SonarModel, accuracy_grid, lookalike_grid
from lost.host.terrain import synthetic_terrain


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    depth = synthetic_terrain((args.size, args.size), seed=7)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        accuracy_grid(grid, SonarModel())
        times.append(time.perf_counter() - start)
    print(f"accuracy_grid {args.size} x {args.size}: median {statistics.median(times):.2f} s (min {min(times):.2f}, max {max(times):.2f})")
    times = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        lookalike_grid(grid, SonarModel(), 0.5, radius_m=600.0)
        times.append(time.perf_counter() - start)
    print(f"lookalike_grid {args.size} x {args.size}: median {statistics.median(times):.2f} s (min {min(times):.2f}, max {max(times):.2f})")
    with tempfile.TemporaryDirectory() as folder:
        path = write_npz(grid, Path(folder) / "map.npz")
        route = Path(folder) / "route.csv"
        far = (args.size - 20) * grid.node_m
        route.write_text(f"east_m,north_m\n{20 * grid.node_m},{20 * grid.node_m}\n{far},{far}\n")
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "lost.host.cli", "plan", str(path), "--route", str(route), "--out", str(Path(folder) / "plan")],
                       check=True, stdout=subprocess.DEVNULL)
        print(f"lost plan {args.size} x {args.size} with a route (read, bound, look-alikes, accuracy.nc, accuracy.png, route): "
              f"{time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
