"""``lost serve --config LIVE.toml``: terrain navigation on the live datagrams (.kmall, NMEA, DVL, depth, USBL) over UDP and serial lines,
estimates out over UDP.

::

    lost serve --config LIVE.toml [--out DIR] [--replace] [--backend NAME [--port PORT] [--baud B] [--variant V]]

The settings are :mod:`lost.host.live.settings`'s (a ``[serve]`` table, the ``[navigation]`` parameters); the
serving is :class:`lost.host.live.server.LiveServer`. The run folder (``--out``, default ``runs/serve``) holds
``log.jsonl`` (one line per record, written as it is served), ``summary.json`` and ``settings.toml`` (a copy
of the settings file). It is written aside and installed whole when the server stops (Ctrl-C, SIGTERM, or
``idle_stop_s``); until then the log is in the folder's temporary twin, whose path the first line prints.

The correlator is ``[navigation] backend`` (or ``--backend``); a device (``fpga`` with ``--port``, ``rtl``) is served
with the software correlator behind it (:mod:`lost.host.live.fallback`): a record the device does not answer is
correlated in software, the device tried again every ``device_retry_s`` seconds.
"""

from __future__ import annotations

import argparse
import contextlib
import shutil
from pathlib import Path

from ..runfolder import run_folder, write_summary
from .common import configure_hardware, hardware_options, map_uncertainty

__all__ = ["register"]


def _cmd_serve(args: argparse.Namespace) -> int:
    from ..io import read_grid
    from ..io.survey_records import SurveyRecorder
    from ..live.fallback import with_fallback
    from ..live.navigator import LiveNavigator
    from ..live.outputs import RunLog, UdpSender
    from ..live.receiver import UdpReceiver
    from ..live.server import LiveServer
    from ..live.settings import address, read_serve_settings
    from ..nav import navigation_parameters

    settings = read_serve_settings(args.config)
    navigation = {**settings.navigation, **({"backend": args.backend} if args.backend else {})}
    params = navigation_parameters(navigation, f"{args.config} [navigation]")
    args.backend = params.backend
    configure_hardware(args)
    device = params.backend in ("fpga", "rtl")
    out = args.out = args.out or Path("runs") / "serve"
    with run_folder(out, replace=args.replace, command="serve", keep=("log.jsonl",)) as folder:
        shutil.copyfile(args.config, folder / "settings.toml")
        grid = read_grid(settings.bathy)
        if grid.crs is None:
            raise ValueError(f"{settings.bathy} has no CRS: received positions (latitude, longitude) cannot be placed on it")
        grid, extra = map_uncertainty(grid, params)
        recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=settings.patch_shape, interval_s=settings.record_s,
                                  window_s=settings.window_s, dr_bias_mps=settings.dr_bias_mps, start_offset_m=settings.start_offset_m,
                                  patch_centre=settings.patch_centre)
        navigator = LiveNavigator(grid, params, settings.estimators, recorder)
        where = [address(listen, "[serve] listen") for listen in settings.listens]
        receiver = UdpReceiver(*where[0], more=tuple(where[1:]), serial=settings.serial, usbl_default_sigma_m=settings.usbl_default_sigma_m)
        sender = UdpSender([address(o, "[serve] outputs") for o in settings.outputs])
        log = RunLog(folder / "log.jsonl")
        ports = "".join(f", serial {p.port} ({p.kind}, {p.baud} baud)" for p in settings.serial)
        print(f"lost serve: listening on {', '.join(f'{h}:{p}' for h, p in receiver.addresses)}{ports}, estimators {', '.join(settings.estimators)}, "
              f"records of {settings.record_s:g} s, out to {', '.join(settings.outputs) or 'nowhere (log only)'}; log {log.path}", flush=True)
        try:
            with with_fallback(params.backend, retry_s=settings.device_retry_s) if device else contextlib.nullcontext() as fallback:
                server = LiveServer(receiver, navigator, sender, log, status_s=settings.status_s, idle_stop_s=settings.idle_stop_s,
                                    reorder_lag_s=settings.reorder_lag_s, reorder_hold_s=settings.reorder_hold_s,
                                    fallback=fallback, queue_max_values=settings.queue_max_values)
                summary = server.run()
        finally:
            log.close()
            sender.close()
        summary.update(extra, parameters=params.as_dict(), record_s=settings.record_s, window_s=recorder.window_s,
                       estimators=list(settings.estimators))
        write_summary(folder / "summary.json", summary)
    print(f"lost serve: {summary['ended']}; {summary['records']} records served; wrote {out}/log.jsonl, summary.json, settings.toml")
    return 0


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost serve``."""
    serve = commands.add_parser("serve", parents=parents, help="navigate on live .kmall, NMEA, DVL, depth, USBL inputs (UDP, serial), estimates out over UDP")
    serve.add_argument("--config", type=Path, required=True, metavar="LIVE.toml", help="the settings: a [serve] table and [navigation]")
    serve.add_argument("--out", type=Path, default=None, metavar="DIR", help="the run folder (default runs/serve)")
    serve.add_argument("--replace", action="store_true", help="replace an earlier run in --out")
    from ..correlator import BACKENDS

    serve.add_argument("--backend", default=None, choices=sorted(BACKENDS), help="the correlator (default: [navigation] backend)")
    hardware_options(serve)
    serve.set_defaults(handler=_cmd_serve)
