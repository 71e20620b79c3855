"""The settings of `lost serve`: a TOML file's ``[serve]`` table (strict: unknown keys refused) and its ``[navigation]``.

::

    [serve]
    listen = "0.0.0.0:4001"                 # HOST:PORT the datagrams arrive on, or several: ["0.0.0.0:4001", "0.0.0.0:4002"]
    bathy = "maps/area.nc"                  # the map, as lost run --bathy (relative to the settings file)
    estimators = ["lost", "pmf", "pf"]      # the bank's names (default: all)
    record_s = 5.0                          # seconds of pings per record, as lost run --survey --record-s
    window_s = 20.0                         # seconds of pings up to a record that make its patch (default record_s)
    patch_shape = [10, 10]                  # nodes of the patch, rows x columns
    patch_centre = "vehicle"                # or "soundings"
    dr_bias_mps = [0.0, 0.0]                # as --dr-bias
    start_offset_m = [0.0, 0.0]             # as --start-offset
    outputs = ["127.0.0.1:5001"]            # where each estimate goes (JSON line and $LOEST sentence)
    status_s = 5.0                          # seconds between status lines on stderr
    idle_stop_s = 0.0                       # stop after this many seconds without a datagram once one came (0: never)
    reorder_lag_s = 0.5                     # a ping waits for a ping this much later in ping time ... (0: not held)
    reorder_hold_s = 0.05                   # ... or this long in wall-clock time, to put pings back into time order
    device_retry_s = 30.0                   # [navigation] backend fpga or rtl: seconds between tries of a device not answering
    usbl_default_sigma_m = 10.0             # 1 sigma (m) of a $PSONLLD/$PSIMSSB fix without error fields (default none: such fixes refused)
    queue_max_values = 10000                # decoded values waiting for the navigation at most (full: the oldest dropped, counted)

    [navigation]                            # NavParameters, as lost run --config's

    [[serial]]                              # a sensor on a serial port (any number of these tables; lost.host.live.serial)
    port = "/dev/ttyUSB0"                   # a device path or a pyserial URL (socket://HOST:PORT, rfc2217://..., loop://)
    kind = "pd6"                            # the lines it carries: "nmea", "pd6" or "json"
    baud = 9600                             # its baud rate (default 9600)
    retry_s = 2.0                           # a port gone or not opening is tried again after this many seconds
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

from pydantic import Field

from ..config import ConfigError, NonNegativeFloat, PositiveFloat, build, read_toml
from ..io.survey_records import DEFAULT_RECORD_S, SURVEY_PATCH_CENTRES
from ..nav import ESTIMATORS
from .backlog import DEFAULT_MAX_VALUES
from .serial import SerialSettings

__all__ = ["ServeSettings", "read_serve_settings", "address"]

_TABLES = ("serve", "navigation", "serial")


def address(text: str, what: str) -> tuple[str, int]:
    """``HOST:PORT`` as a (host, port) pair; a :class:`ConfigError` naming ``what`` otherwise."""
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 0 <= int(port) < 65536:
        raise ConfigError(f"{what} must be HOST:PORT with a port from 0 to 65535, got {text!r}")
    return host, int(port)


@dataclass(frozen=True)
class ServeSettings:
    """``[serve]`` (see the module); ``navigation`` is the ``[navigation]`` table, validated by the navigation's own layer."""

    listen: str | tuple[str, ...]
    bathy: str
    estimators: tuple[str, ...] = ESTIMATORS
    record_s: PositiveFloat = DEFAULT_RECORD_S
    window_s: PositiveFloat | None = None
    patch_shape: tuple[Annotated[int, Field(gt=0)], Annotated[int, Field(gt=0)]] = (10, 10)
    patch_centre: str = "vehicle"
    dr_bias_mps: tuple[float, float] = (0.0, 0.0)
    start_offset_m: tuple[float, float] = (0.0, 0.0)
    outputs: tuple[str, ...] = ()
    status_s: PositiveFloat = 5.0
    idle_stop_s: NonNegativeFloat = 0.0
    reorder_lag_s: NonNegativeFloat = 0.5
    reorder_hold_s: NonNegativeFloat = 0.05
    device_retry_s: PositiveFloat = 30.0
    usbl_default_sigma_m: PositiveFloat | None = None
    queue_max_values: Annotated[int, Field(gt=0)] = DEFAULT_MAX_VALUES
    navigation: dict = field(default_factory=dict)
    serial: tuple[SerialSettings, ...] = ()

    def __post_init__(self) -> None:
        if not self.listen or len(set(self.listens)) != len(self.listens):
            raise ConfigError(f"[serve] listen must be HOST:PORT or a list of them, each once, got {self.listen!r}")
        for listen in self.listens:
            address(listen, "[serve] listen")
        for output in self.outputs:
            address(output, "[serve] outputs")
        unknown = sorted(set(self.estimators) - set(ESTIMATORS))
        if unknown or not self.estimators or len(set(self.estimators)) != len(self.estimators):
            raise ConfigError(f"[serve] estimators must be some of {list(ESTIMATORS)}, each once, got {list(self.estimators)}")
        if self.patch_centre not in SURVEY_PATCH_CENTRES:
            raise ConfigError(f"[serve] patch_centre must be one of {list(SURVEY_PATCH_CENTRES)}, got {self.patch_centre!r}")
        if not all(math.isfinite(v) for v in (*self.dr_bias_mps, *self.start_offset_m)):
            raise ConfigError("[serve] dr_bias_mps and start_offset_m must be finite")


    @property
    def listens(self) -> tuple[str, ...]:
        """The addresses listened on: every one takes every input kind, told by its content."""
        return (self.listen,) if isinstance(self.listen, str) else tuple(self.listen)


def read_serve_settings(path: Path) -> ServeSettings:
    """The settings of ``path``; the map's path relative to the file's folder.

    Raises
    ------
    ConfigError
        Not TOML, no ``[serve]`` table, a table or key not known, a value of the wrong type or out of range (named).
    FileNotFoundError
        No file at ``path``.
    """
    data = read_toml(path, "lost serve settings file")
    unknown = sorted(set(data) - set(_TABLES))
    if unknown:
        raise ConfigError(f"{path}: unknown table(s) {unknown}; known are {list(_TABLES)}")
    if "serve" not in data:
        raise ConfigError(f"{path} has no [serve] table (listen, bathy, ...)")
    table = dict(data["serve"]) if isinstance(data["serve"], dict) else data["serve"]
    settings = build(ServeSettings, table, "serve")
    navigation = data.get("navigation", {})
    if not isinstance(navigation, dict):
        raise ConfigError(f"{path}: [navigation] must be a table")
    serial = data.get("serial", [])
    if not isinstance(serial, list) or not all(isinstance(table, dict) for table in serial):
        raise ConfigError(f"{path}: serial ports are [[serial]] tables (port, kind, baud, retry_s), got {serial!r}")
    ports = tuple(build(SerialSettings, table, f"serial.{k}") for k, table in enumerate(serial))
    if len({p.port for p in ports}) != len(ports):
        raise ConfigError(f"{path}: a serial port is named twice in [[serial]]: {[p.port for p in ports]}")
    bathy = Path(settings.bathy)
    bathy = bathy if bathy.is_absolute() else path.parent / bathy
    return ServeSettings(**{**settings.__dict__, "bathy": str(bathy), "navigation": navigation, "serial": ports})
