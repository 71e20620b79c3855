"""Reading speed of the survey readers (soundings per second per format) and the memory of reading a large file.

    python benchmarks/read_speed.py [--repeats 7] [--big-gb 1.0] [--big-from export|investigator] [--big-format all|gsf]
                                    [--out build/bench/read_speed.json]

Per format, every real file of ../shared/data/real_survey of that format is read through
``lost.host.io.survey.open_survey`` (pings projected to the file's UTM zone, looked up once beforehand;
beams placed) ``--repeats`` times after one warm-up read; the table gives the median and the 10th percentile (the slowest tenth) of soundings per
second over the repeats. Then a Kongsberg ``.all`` file of ``--big-gb`` gigabytes is made, by default by the export
(``--big-from export``: the ``short`` scenario's tow with 512 beams a ping, :func:`simulated_pings`, written by
:func:`write_all_pings` streaming, the tow repeated with its times shifted by its duration until the size is
reached; ``--big-format gsf`` writes it as GSF by :func:`write_gsf_pings` instead), or from the RV Investigator
file's datagrams repeated with their times shifted (checksums recomputed), and read by ``summarize_survey`` in a
child process whose peak resident memory is reported beside the file's size: reading is streamed when the first is
a small fraction of the second. The peak is the child's own ``VmHWM`` (``/proc/self/status``): its ``ru_maxrss``
would not do, as Linux carries the parent's peak into a child started by vfork and exec.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT / ".." / "shared" / "data" / "real_survey"
FORMATS = {"kongsberg-all": "*/*.all", "kmall": "*/*.kmall", "gsf": "*/*.gsf"}
INVESTIGATOR = REAL / "ausseabed_investigator_em710_all" / "0000_20200107_035504_Investigator_em710.all"


def file_crs(files: list[Path]) -> dict[Path, str]:
    """Each file's projected CRS (the UTM zone of its first ping), looked up once, outside the timing."""
    from lost.host.io.survey import open_survey

    crs = {}
    for path in files:
        survey = open_survey(path)
        next(iter(survey), None)
        crs[path] = survey.crs
    return crs


def soundings_per_second(files: list[Path], crs: dict[Path, str]) -> float:
    from lost.host.io.survey import open_survey

    start = time.perf_counter()
    soundings = 0
    for path in files:
        for ping in open_survey(path, crs=crs[path]):
            soundings += ping.beams
            ping.beam_east_m  # noqa: B018  the beams placed, as a consumer would
    return soundings / (time.perf_counter() - start)


def make_big_all(path: Path, gigabytes: float) -> int:
    """The Investigator file repeated, each copy 8 s later than the one before; returns the number of copies."""
    data = INVESTIGATOR.read_bytes()
    frames, at = [], 0
    while at < len(data):
        length = int.from_bytes(data[at:at + 4], "little")
        frames.append((at, length + 4))
        at += length + 4
    copies = max(1, int(gigabytes * 1e9 // len(data)))
    with path.open("wb") as out:
        for k in range(copies):
            chunk = bytearray(data)
            for at, size in frames:
                time_ms = int.from_bytes(chunk[at + 12:at + 16], "little") + 8000 * k
                chunk[at + 12:at + 16] = time_ms.to_bytes(4, "little")
                checksum = int(np.frombuffer(chunk, np.uint8, size - 8, at + 5).sum()) & 0xFFFF
                chunk[at + size - 2:at + size] = checksum.to_bytes(2, "little")
            out.write(chunk)
    return copies


def make_big_export(path: Path, gigabytes: float, beams: int = 512, file_format: str = "all") -> int:
    """A simulated tow exported as ``.all`` (or GSF), repeated (times shifted by the tow's duration) to ``gigabytes``; returns the copies."""
    from dataclasses import replace
    from itertools import count

    from lost.host.io.gsf_write import write_gsf_pings
    from lost.host.io.kongsberg_all import write_all_pings
    from lost.host.io.simulated import simulated_pings
    from lost.host.scenario import builtin_scenario_path, load_scenario

    scenario = load_scenario(builtin_scenario_path("short"))
    scenario = replace(scenario, sensors={**scenario.sensors, "sonar": replace(scenario.sensors["sonar"], beams=beams)})
    _, _, pings = simulated_pings(scenario)
    tow = list(pings)
    span = tow[-1].time_s - tow[0].time_s + 1.0
    target, written = gigabytes * 1e9, [0]

    def repeated():
        for k in count():
            for ping in tow:
                yield replace(ping, time_s=ping.time_s + k * span)
            written[0] = k + 1
            if path.with_name(path.name + ".partial").stat().st_size >= target:
                return

    (write_gsf_pings if file_format == "gsf" else write_all_pings)(repeated(), path)
    return written[0]


def read_big_in_child(path: Path) -> dict:
    code = (
        "import json, resource, time, sys\n"
        "from lost.host.io.survey_summary import summarize_survey\n"
        "start = time.perf_counter()\n"
        f"s = summarize_survey({str(path)!r})\n"
        "seconds = time.perf_counter() - start\n"
        "hwm = [line.split()[1] for line in open('/proc/self/status') if line.startswith('VmHWM:')]\n"
        "peak = int(hwm[0]) / 1024 if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024\n"
        "print(json.dumps({'pings': s['pings'], 'soundings': s['soundings'], 'seconds': seconds, "
        "'peak_rss_mb': peak, 'skipped': s['skipped']}))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--big-gb", type=float, default=1.0, help="size of the large .all file; 0 skips it")
    parser.add_argument("--big-from", choices=("export", "investigator"), default="export",
                        help="the large file: a simulated tow exported (default), or the Investigator file repeated")
    parser.add_argument("--big-format", choices=("all", "gsf"), default="all", help="the large export's format")
    parser.add_argument("--skip-formats", action="store_true", help="only the large file")
    parser.add_argument("--out", type=Path, default=ROOT / "build" / "bench" / "read_speed.json")
    args = parser.parse_args()
    if not REAL.is_dir():
        print(f"no real survey files at {REAL}", file=sys.stderr)
        return 1
    results: dict = {"formats": {}}
    print(f"{'format':<14} {'files':>5} {'median soundings/s':>19} {'10th pct':>10}")
    for name, pattern in ({} if args.skip_formats else FORMATS).items():
        files = sorted(REAL.glob(pattern))
        crs = file_crs(files)
        soundings_per_second(files, crs)  # warm-up: imports, caches
        speeds = np.array([soundings_per_second(files, crs) for _ in range(args.repeats)])
        row = {"files": len(files), "median": float(np.median(speeds)), "p10": float(np.percentile(speeds, 10)), "repeats": args.repeats}
        results["formats"][name] = row
        print(f"{name:<14} {row['files']:>5} {row['median']:>19,.0f} {row['p10']:>10,.0f}")
    if args.big_gb > 0:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        if args.big_format == "gsf" and args.big_from != "export":
            parser.error("--big-format gsf needs --big-from export")
        big = args.out.parent / f"big.{args.big_format}"
        start = time.perf_counter()
        if args.big_from == "export":
            copies = make_big_export(big, args.big_gb, file_format=args.big_format)
        else:
            copies = make_big_all(big, args.big_gb)
        made_s = time.perf_counter() - start
        read = read_big_in_child(big)
        read.update(file_mb=big.stat().st_size / 1e6, copies=copies, made_from=args.big_from, file_format=args.big_format, made_s=made_s,
                    soundings_per_s=read["soundings"] / read["seconds"])
        results["big_all"] = read
        print(f"big .{args.big_format} ({args.big_from}, made in {made_s:.0f} s): {read['file_mb']:,.0f} MB, {read['pings']:,} pings, "
              f"{read['soundings']:,} soundings in {read['seconds']:.1f} s "
              f"({read['soundings_per_s']:,.0f}/s), peak memory {read['peak_rss_mb']:,.0f} MB")
        big.unlink()
    results["self_peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
