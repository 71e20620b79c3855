"""``lost replay SOURCE --to HOST:PORT``: a recorded survey or a simulated scenario sent as the live datagrams over UDP.

SOURCE is a survey file (any format ``open_survey`` reads; several of one format in time order) or a scenario
(a shipped name or a SCENARIO.toml, its pings from :mod:`lost.host.io.simulated`). The datagrams are those of
:mod:`lost.host.live.stream`, sent at their own times divided by ``--speed`` (``0``: as fast as possible), with
the optional faults drawn from ``--seed``. It writes no file. It prints one line when it starts (what, where,
how fast) and a summary when done: pings, datagrams sent per kind and bytes, the faults drawn, and what the
reader skipped.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter
from pathlib import Path

from ..errors import UsageError

__all__ = ["register"]

_LARGEST_UDP = 65_507  # a UDP datagram's largest payload over IPv4
_SMALLEST_PART = 512  # a partition's header, partition and closing length leave room for data
_USBL_NAMES = {"json": "JSON", "psonlld": "$PSONLLD", "psimssb": "$PSIMSSB"}


def _address(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise argparse.ArgumentTypeError(f"--to must be HOST:PORT with a port from 1 to 65535, got {text!r}")
    return host, int(port)


def _probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"a probability from 0 to 1, got {text!r}")
    return value


def _speed(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not (value >= 0.0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"--speed must be 0 (as fast as possible) or a positive factor of real time, got {text!r}")
    return value


def _count(text: str) -> int:
    value = int(text) if text.isdigit() else 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"--reorder-by must be a whole number of datagrams from 1, got {text!r}")
    return value


def _datagram_bytes(text: str) -> int:
    value = int(text) if text.isdigit() else -1
    if not _SMALLEST_PART <= value <= _LARGEST_UDP:
        raise argparse.ArgumentTypeError(f"--max-datagram-bytes must be from {_SMALLEST_PART} to {_LARGEST_UDP} (one UDP datagram), got {text!r}")
    return value


def _pings(sources: list[str], dvl: str | None, usbl: str | None = None):
    """The pings of the source, what it skipped (a Counter filled while iterating), what it is, the vehicle's datagrams (or None)."""
    paths = [Path(s) for s in sources]
    absent = [str(p) for p in paths if not p.exists() and (p.suffix not in ("", ".toml") or len(p.parts) > 1)]
    if absent:
        raise FileNotFoundError(f"no survey file or scenario at {', '.join(absent)}")
    if all(p.suffix != ".toml" and p.is_file() for p in paths):
        from ..io.survey import open_survey

        if dvl not in (None, "none"):
            raise UsageError(f"--dvl {dvl}: a survey file has no DVL to send (the vehicle's DVL and depth come with a simulated scenario)")
        if usbl not in (None, "none"):
            raise UsageError(f"--usbl {usbl}: a survey file has no USBL fixes to send (they come with a simulated scenario with a USBL)")
        survey = open_survey(paths)
        return iter(survey), survey.skipped, f"{survey.format} survey {', '.join(p.name for p in paths)}", None
    if len(sources) != 1:
        raise UsageError("give survey files, or one scenario (a shipped name or a SCENARIO.toml)")
    from ..io.simulated import EPOCH_S, simulated_pings
    from ..live.stream import vehicle_datagrams
    from ..scenario import builtin_scenario_path, load_scenario, simulate

    path = paths[0] if paths[0].suffix == ".toml" or paths[0].is_file() else builtin_scenario_path(sources[0])
    scenario = load_scenario(path)
    _, crs, pings = simulated_pings(scenario)
    dvl = dvl or "pd6"
    with_usbl = usbl != "none" and scenario.sensors["usbl"].enabled
    if usbl not in (None, "none") and not with_usbl:
        raise UsageError(f"--usbl {usbl}: scenario {scenario.name!r} has no USBL ([sensors.usbl] enabled = false)")
    if dvl == "none" and not with_usbl:
        return pings, Counter(), f"scenario {scenario.name!r} (simulated pings)", None
    _, records = simulate(scenario)  # the same tow again (its seed): the simulator's DVL, depth and USBL readings
    sent = (([f"the vehicle's DVL and depth as {dvl.upper()}"] if dvl != "none" else [])
            + ([f"its USBL fixes as {_USBL_NAMES[usbl or 'json']}"] if with_usbl else []))
    return (pings, Counter(), f"scenario {scenario.name!r} (simulated pings, {' and '.join(sent)})",
            vehicle_datagrams(records, crs, dvl_format=dvl, epoch_s=EPOCH_S, usbl=with_usbl, usbl_format=usbl or "json"))


def _cmd_replay(args: argparse.Namespace) -> int:
    from ..live.stream import Faults, live_datagrams, send_datagrams, with_faults

    faults = Faults(loss=args.loss, reorder=args.reorder, duplicate=args.duplicate, seed=args.seed, reorder_by=args.reorder_by)
    pings, skipped, what, vehicle = _pings(args.source, args.dvl, args.usbl)
    counted = Counter()

    def counting(stream):
        for ping in stream:
            counted["pings"] += 1
            yield ping

    speed = "as fast as possible" if args.speed == 0 else f"at {args.speed:g}x real time"
    print(f"lost replay: {what} to {args.to[0]}:{args.to[1]} over UDP, {speed}", flush=True)
    drawn: Counter = Counter()
    datagrams = live_datagrams(counting(pings), max_datagram_bytes=args.max_datagram_bytes, vehicle=vehicle)
    started = time.monotonic()
    sent = send_datagrams(with_faults(datagrams, faults, drawn) if faults.any else datagrams, args.to, speed=args.speed)
    vehicle_count = sum(sent[f"{kind} datagrams sent"] for kind in ("pd6", "json", "usbl"))
    vehicle_sent = f", {vehicle_count} of the vehicle's sensors" if vehicle is not None else ""
    print(f"sent {counted['pings']} pings as {sent['kmall datagrams sent']} .kmall and {sent['nmea datagrams sent']} NMEA datagrams{vehicle_sent} "
          f"({sent['bytes sent']:,} bytes) in {time.monotonic() - started:.1f} s")
    if faults.any:
        print(f"faults (seed {faults.seed}): of {drawn['datagrams']} datagrams {drawn['lost']} lost, {drawn['duplicated']} duplicated, "
              f"{drawn['reordered']} reordered (.kmall {drawn['lost kmall']} lost, {drawn['duplicated kmall']} duplicated; "
              f"NMEA {drawn['lost nmea']} lost, {drawn['duplicated nmea']} duplicated)")
    for reason, count in sorted(skipped.items()):
        print(f"  skipped by the reader: {reason}: {count}")
    return 0


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost replay``."""
    from ..io.kmall_write import UDP_PART_BYTES
    from ..live.stream import USBL_FORMATS

    replay = commands.add_parser("replay", parents=parents, help="send a survey or a scenario as live .kmall and NMEA datagrams over UDP")
    replay.add_argument("source", nargs="+", help="survey files (.all, .kmall, GSF) of one format, or a scenario name or SCENARIO.toml")
    replay.add_argument("--to", type=_address, required=True, metavar="HOST:PORT", help="where to send the UDP datagrams")
    replay.add_argument("--speed", type=_speed, default=1.0, help="factor of real time (default 1; 0: as fast as possible)")
    replay.add_argument("--loss", type=_probability, default=0.0, metavar="P", help="probability that a datagram is lost")
    replay.add_argument("--reorder", type=_probability, default=0.0, metavar="P", help="probability that a datagram is sent after the next")
    replay.add_argument("--reorder-by", type=_count, default=1, metavar="N",
                        help="a reordered datagram is sent after the next N (default 1; a ping is about 6 datagrams)")
    replay.add_argument("--duplicate", type=_probability, default=0.0, metavar="P", help="probability that a datagram is sent twice")
    replay.add_argument("--seed", type=int, default=0, help="seed of the faults' generator (default 0)")
    replay.add_argument("--dvl", choices=("pd6", "json", "none"), default=None,
                        help="a scenario's DVL and depth as Teledyne PD6 (the default) or JSON lines, or not sent (none); survey files have none")
    replay.add_argument("--usbl", choices=(*USBL_FORMATS, "none"), default=None,
                        help="a scenario's USBL fixes as JSON lines (json, the default when it has a USBL), as a USBL's own sentences "
                             "(psonlld: Sonardyne, with the error ellipse; psimssb: Kongsberg, geographic), or not sent (none)")
    replay.add_argument("--max-datagram-bytes", type=_datagram_bytes, default=UDP_PART_BYTES, metavar="B",
                        help=f"an MRZ larger than this is sent in partitions (default {UDP_PART_BYTES})")
    replay.set_defaults(handler=_cmd_replay)
