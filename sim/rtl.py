"""The ``rtl`` correlator backend: the generated Verilog of a correlator, run on Verilator.

``lost.host.correlate(..., backend="rtl")`` lands here (imported lazily, so the host needs neither
Amaranth nor Verilator until it is asked for RTL). The gateware is built for the exact map and patch
shape of the call: the first call at a shape generates the Verilog and compiles it (a minute or two
at 501 x 501), later calls at that shape reuse the build, each then simulating one correlation through
the ports of the contract (about 40 k clocks a second for the 1-lane window core). That makes it the
backend for checking the gateware on one's own data, bit for bit against the others, not for
navigating: every new sub-map shape is a new build.

Builds live under ``$LOST_RTL_CACHE`` (default ``~/.cache/lost/rtl``), one folder per variant and
shape, rebuilt when the generated Verilog changes. ``$LOST_RTL_VARIANT`` picks the gateware among
:data:`lost.hdl.generate.VARIANTS` (default ``window_correlator_l1``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from lost.hdl.generate import VARIANTS, write_variants

from .cocotb.correlator import ENVIRONMENT_VARIABLE, BenchConfig
from .cocotb.job import JOB_VARIABLE, RESULT_VARIABLE
from .verilator import build_and_test, build_folder_lock

__all__ = ["DEFAULT_VARIANT", "RtlError", "cache_root", "rtl_surface"]

DEFAULT_VARIANT = "window_correlator_l1"


class RtlError(RuntimeError):
    """The simulation did not produce a surface; the message names the log to read."""


def cache_root() -> Path:
    """Where builds are kept: ``$LOST_RTL_CACHE``, else ``~/.cache/lost/rtl``."""
    configured = os.environ.get("LOST_RTL_CACHE")
    return Path(configured) if configured else Path.home() / ".cache" / "lost" / "rtl"


def _bench_config(name: str, map_shape: tuple[int, int], patch_shape: tuple[int, int]) -> BenchConfig:
    if name not in VARIANTS:
        raise ValueError(f"LOST_RTL_VARIANT must be one of {sorted(VARIANTS)}, got {name!r}")
    if name.startswith("recursive"):
        return BenchConfig(variant="recursive", map_shape=map_shape, patch_shape=patch_shape)
    return BenchConfig(variant="window", map_shape=map_shape, patch_shape=patch_shape, lanes=int(name.rsplit("_l", 1)[1]))


def rtl_surface(terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> np.ndarray:
    """The surface the simulated gateware computes for validated inputs (see :func:`lost.host.correlate`).

    Raises
    ------
    RtlError
        The build or the simulation failed, or left no result; the message names the log.
    """
    name = os.environ.get("LOST_RTL_VARIANT", DEFAULT_VARIANT)
    config = _bench_config(name, tuple(terrain.shape), tuple(patch.shape))
    (H, W), (h, w) = config.map_shape, config.patch_shape
    folder = cache_root() / f"{name}-{H}x{W}-{h}x{w}"
    with build_folder_lock(folder), tempfile.TemporaryDirectory(prefix="job-", dir=folder) as scratch:
        job, result = Path(scratch) / "job.npz", Path(scratch) / "result.npz"
        np.savez(job, terrain=terrain, patch=patch, mask=mask, mean_compensation=np.bool_(mean_compensation))
        (source,) = write_variants(folder, names=[name], map_shape=config.map_shape, patch_shape=config.patch_shape)
        environment = {ENVIRONMENT_VARIABLE: config.to_json(), JOB_VARIABLE: str(job), RESULT_VARIABLE: str(result)}
        try:
            build_and_test(sources=[source], toplevel=name, test_module="lost.sim.cocotb.job", build_dir=folder,
                           extra_env=environment)
        except SystemExit as exit_:  # cocotb's runner exits when the simulator fails
            raise RtlError(f"the {name} simulation failed (exit {exit_.code}); see {folder / 'build.log'} and {folder / 'test.log'}") from None
        if not result.exists():
            raise RtlError(f"the {name} simulation wrote no surface; see {folder / 'test.log'}")
        with np.load(result) as answer:
            return answer["surface"]
