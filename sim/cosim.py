"""The device co-simulated on Verilator, served on a Unix socket for the host's ``CosimTransport``.

``python -m lost.sim.cosim --socket PATH --build-dir DIR --config JSON`` generates the Verilog of
:class:`lost.hdl.device.CorrelatorDevice` for the configuration, builds it with Verilator (once per
configuration and Verilog text, under ``DIR``) and runs the cocotb bench :mod:`lost.sim.cocotb.device`,
which connects to the socket and turns its bytes into bits on the device's ``rx`` pin and the bits of
its ``tx`` pin into bytes, until the host closes the socket.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from lost.model.variants import DEFAULT_VARIANT, variant

__all__ = ["DeviceConfig", "SOCKET_VARIABLE", "build_device", "main"]

SOCKET_VARIABLE = "LOST_COSIM_SOCKET"
CONFIG_VARIABLE = "LOST_COSIM_CONFIG"
TOPLEVEL = "lost_device"


@dataclass(frozen=True)
class DeviceConfig:
    """The device a co-simulation builds: variant, sizes, UART divisor and frame timeout.

    The defaults are small enough that a build takes a couple of minutes and a correlation of a
    navigation's sub-map (a search half-width of a few nodes) a fraction of a second.
    """

    variant: str = DEFAULT_VARIANT
    tile_shape: tuple[int, int] = (32, 32)
    area_shape: tuple[int, int] = (24, 24)
    patch_shape: tuple[int, int] = (10, 10)
    exclusion_radius: int = 5
    divisor: int = 4
    frame_timeout: int = 2000

    def __post_init__(self) -> None:
        variant(self.variant)
        object.__setattr__(self, "tile_shape", tuple(self.tile_shape))
        object.__setattr__(self, "area_shape", tuple(self.area_shape))
        object.__setattr__(self, "patch_shape", tuple(self.patch_shape))

    def to_json(self) -> str:
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> DeviceConfig:
        return cls(**json.loads(text))

    def device(self):
        from lost.hdl.device import CorrelatorDevice

        return CorrelatorDevice(variant=self.variant, tile_shape=self.tile_shape, area_shape=self.area_shape,
                                patch_shape=self.patch_shape, exclusion_radius=self.exclusion_radius,
                                divisor=self.divisor, frame_timeout=self.frame_timeout)

    @property
    def folder_name(self) -> str:
        (TH, TW), (AH, AW), (h, w) = self.tile_shape, self.area_shape, self.patch_shape
        digest = hashlib.sha1(self.to_json().encode()).hexdigest()[:8]
        return f"{self.variant}-t{TH}x{TW}-a{AH}x{AW}-p{h}x{w}-{digest}"


def build_device(config: DeviceConfig, build_dir: Path) -> Path:
    """Write the device's Verilog under ``build_dir`` (only when its text changed); return the file."""
    from lost.hdl.flow.generate import write_verilog

    return write_verilog(config.device(), name=TOPLEVEL, out=build_dir)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.sim.cosim", description=__doc__.splitlines()[0])
    parser.add_argument("--socket", required=True, help="Unix socket the host listens on")
    parser.add_argument("--build-dir", type=Path, required=True)
    parser.add_argument("--config", required=True, help="DeviceConfig as JSON")
    args = parser.parse_args(argv)
    from .verilator import build_and_test, build_folder_lock

    config = DeviceConfig.from_json(args.config)
    folder = args.build_dir / config.folder_name
    with build_folder_lock(folder):
        source = build_device(config, folder)
        build_and_test(sources=[source], toplevel=TOPLEVEL, test_module="lost.sim.cocotb.device", build_dir=folder,
                       extra_env={SOCKET_VARIABLE: args.socket, CONFIG_VARIABLE: config.to_json()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
