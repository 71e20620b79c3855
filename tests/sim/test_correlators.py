"""Each correlator variant's generated Verilog on Verilator with cocotb 2 (``lost.sim.cocotb.correlator``).

Every surface value and the best fit are compared with ``lost.model``; with ready held high every
beat's cycle is compared with the variant's cycle model. The window core runs with 4 lanes at 160 x 170 (a 10 x 10
patch; 161 placements a row, the last beat partial) and at a small size, with 1 lane at 64 x 70; the recursive core
at a reduced size. ``make sim-full`` runs the recursive core and both window cores at the paper's full size (501 x 501
map, 10 x 10 patch; each about 4-8 minutes here).
"""

from pathlib import Path

import pytest

from lost.hdl.flow.generate import write_variants
from lost.sim.cocotb.correlator import ENVIRONMENT_VARIABLE, BenchConfig
from lost.sim.verilator import build_and_test, build_folder_lock

BUILD = Path(__file__).resolve().parents[2] / "build" / "sim"

CASES = [
    pytest.param(BenchConfig(variant="window", map_shape=(501, 501), patch_shape=(10, 10), lanes=1, seed=1),
                 id="window-l1-501x501-10x10", marks=pytest.mark.slow),
    pytest.param(BenchConfig(variant="window", map_shape=(64, 70), patch_shape=(10, 10), lanes=1, seed=6),
                 id="window-l1-64x70-10x10"),
    pytest.param(BenchConfig(variant="window", map_shape=(501, 501), patch_shape=(10, 10), lanes=4, seed=2),
                 id="window-l4-501x501-10x10", marks=pytest.mark.slow),
    pytest.param(BenchConfig(variant="window", map_shape=(160, 170), patch_shape=(10, 10), lanes=4, seed=7),
                 id="window-l4-160x170-10x10"),
    # 27 placements per row: every row ends on a beat of 3 values out of 4.
    pytest.param(BenchConfig(variant="window", map_shape=(23, 30), patch_shape=(5, 4), lanes=4,
                             exclusion_radius=2, seed=3),
                 id="window-l4-23x30-5x4"),
    pytest.param(BenchConfig(variant="recursive", map_shape=(32, 40), patch_shape=(10, 10), seed=4),
                 id="recursive-32x40-10x10"),
    pytest.param(BenchConfig(variant="recursive", map_shape=(501, 501), patch_shape=(10, 10), seed=5),
                 id="recursive-501x501-10x10", marks=pytest.mark.slow),
]


def _module_name(config: BenchConfig) -> str:
    return config.registered.name


@pytest.mark.parametrize("config", CASES)
def test_correlator_on_verilator(config: BenchConfig):
    (H, W), (h, w) = config.map_shape, config.patch_shape
    folder = BUILD / f"{config.variant}-l{config.lanes}-{H}x{W}-{h}x{w}-r{config.exclusion_radius}"
    name = _module_name(config)
    with build_folder_lock(folder):
        (source,) = write_variants(
            folder,
            names=[name],
            map_shape=config.map_shape,
            patch_shape=config.patch_shape,
            depth_bits=config.depth_bits,
            exclusion_radius=config.exclusion_radius,
        )
        build_and_test(
            sources=[source],
            toplevel=name,
            test_module="lost.sim.cocotb.correlator",
            build_dir=folder,
            extra_env={ENVIRONMENT_VARIABLE: config.to_json(), "PYTHONFAULTHANDLER": "1"},
        )
