"""The pipeline driver on hand-built tows, where the right answer is known exactly."""

import numpy as np
import pytest

from lost.host.grid import Grid
from lost.host.nav import NavParameters, run_lost
from lost.host.records import NavRecords, SonarPatch
from lost.host.terrain import synthetic_terrain

NODE = 10.0
SIDE = 9  # odd: the patch centre is a node


def _tow(n=12, *, start=(300.0, 200.0), speed=(0.0, 10.0), depth_grid=None, bias=3.0, ship_ahead=500.0):
    """A vehicle moving one node per second north over a rough map, patches cut exactly from it."""
    depth = synthetic_terrain((80, 60), seed=4, roughness_m=10.0, hurst=0.5) if depth_grid is None else depth_grid
    grid = Grid(depth, 0.0, 0.0, NODE)
    t = np.arange(n, dtype=float)
    truth = np.asarray(start) + np.outer(t, speed)
    half = SIDE // 2
    patches = []
    for x, y in truth:
        row, col = (int(round(v)) for v in grid.row_col(x, y))
        if half <= row < depth.shape[0] - half and half <= col < depth.shape[1] - half:
            patches.append(SonarPatch(depth[row - half : row + half + 1, col - half : col + half + 1] + bias, NODE))
        else:
            patches.append(None)
    records = NavRecords(
        t_s=t,
        ship_x_m=truth[:, 0],
        ship_y_m=truth[:, 1] + ship_ahead,
        ship_heading_deg=np.zeros(n),
        vehicle_depth_m=np.zeros(n),
        altitude_m=np.full(n, np.nan),
        vel_x_mps=np.full(n, speed[0]),
        vel_y_mps=np.full(n, speed[1]),
        slant_range_m=np.full(n, np.nan),
        cable_out_m=np.full(n, ship_ahead),  # depth 0: the lay-back is the whole cable, right on the truth
        sonar=tuple(patches),
        truth_x_m=truth[:, 0],
        truth_y_m=truth[:, 1],
    )
    return grid, records, truth


def _replace(records, **changes):
    fields = {name: getattr(records, name) for name in records.__dataclass_fields__}
    return NavRecords(**{**fields, **changes})


def test_patch_mle_finds_the_vehicle_from_an_offset_start():
    grid, records, truth = _tow()
    result = run_lost(records, grid, NavParameters(initial_offset_m=(60.0, -40.0)))
    assert np.allclose(result.estimate[0], truth[0] + (60.0, -40.0))
    assert np.all(result.mle_source[1:] == "patch")
    assert np.max(np.hypot(*(result.mle[1:] - truth[1:]).T)) < 1.0
    # Along track the estimate is the MLE's; the cross-track error (east here) decays through the CAT.
    assert np.allclose(result.estimate[1:, 1], result.mle[1:, 1])
    cross_error = np.abs(result.estimate[:, 0] - truth[:, 0])
    assert np.all(np.diff(cross_error) < 0)
    assert result.counts["mle_updates"] == len(records) - 1


def test_a_patch_centred_behind_the_vehicle_finds_the_vehicle():
    # Each patch is cut 3 nodes south and 1 west of the vehicle, and says so: the MLE is the vehicle's.
    grid, records, truth = _tow(n=8, start=(300.0, 240.0))
    depth, half = grid.depth_m, SIDE // 2
    behind = []
    for x, y in truth:
        row, col = (int(round(v)) for v in grid.row_col(x, y))
        behind.append(SonarPatch(depth[row - 3 - half : row - 3 + half + 1, col - 1 - half : col - 1 + half + 1] + 3.0,
                                 NODE, centre_offset_m=(-NODE, -3 * NODE)))
    result = run_lost(_replace(records, sonar=tuple(behind)), grid, NavParameters(initial_offset_m=(20.0, 20.0)))
    assert np.max(np.hypot(*(result.mle[1:] - truth[1:]).T)) < 1.0
    # Without the offset the same patches put the vehicle where the patch is.
    plain = tuple(SonarPatch(patch.depth_m, NODE) for patch in behind)
    wrong = run_lost(_replace(records, sonar=plain), grid, NavParameters(initial_offset_m=(20.0, 20.0)))
    assert np.allclose(wrong.mle[1:] - truth[1:], (-NODE, -3 * NODE), atol=1.0)


def test_the_tracker_restarts_after_a_long_gap_instead_of_jumping():
    # Patches at 1-3 s, none for 60 s, then patches again: a stale w times 60 s would throw the estimate.
    grid, records, truth = _tow(n=70, start=(300.0, 20.0), speed=(0.0, 8.0))
    gap = tuple(patch if n < 4 or n > 63 else None for n, patch in enumerate(records.sonar))
    records = _replace(records, sonar=gap)
    start = (40.0, 0.0)
    restarted = run_lost(records, grid, NavParameters(initial_offset_m=start))
    assert restarted.counts["cat_restarts"] == 1
    # Cross track is east here: from w = 0 the estimate creeps toward the MLE, w growing by f_a (0.05) a second.
    cross_step = np.abs(np.diff(restarted.estimate[63:68, 0]))
    assert np.all(cross_step <= 0.05 * np.arange(1, 5) + 1e-9)
    never = run_lost(records, grid, NavParameters(initial_offset_m=start, cat_restart_s=1e9))
    assert "cat_restarts" not in never.counts
    # The patent's eq. 7 with the gap as dt: w (at f_v's 1 m/s by then) times 61 s, past the MLE.
    assert abs(never.estimate[64, 0] - never.estimate[63, 0]) > 50.0


def test_every_backend_gives_the_same_track():
    grid, records, _ = _tow(n=6)
    a = run_lost(records, grid, NavParameters(backend="software", initial_offset_m=(30.0, 20.0)))
    b = run_lost(records, grid, NavParameters(backend="model", initial_offset_m=(30.0, 20.0)))
    assert np.array_equal(a.estimate, b.estimate) and np.array_equal(a.mle, b.mle, equal_nan=True)


def test_a_hole_excludes_every_placement_that_puts_a_sounding_on_it_beyond_the_allowed_share():
    depth = synthetic_terrain((80, 60), seed=4, roughness_m=10.0, hurst=0.5)
    grid, records, truth = _tow(n=6, depth_grid=depth)
    row, col = (int(round(v)) for v in grid.row_col(*truth[3]))
    holed = depth.copy()
    holed[row, col] = np.nan  # under the vehicle at record 3
    grid_holed = Grid(holed, 0.0, 0.0, NODE)
    result = run_lost(records, grid_holed, NavParameters(max_hole_share=0.0))
    # Every placement covering the hole is out, the true one among them: no match on the truth.
    mle_error = np.hypot(*(result.mle[3] - truth[3]))
    assert not mle_error < NODE
    clean = run_lost(records, grid, NavParameters())
    assert np.hypot(*(clean.mle[3] - truth[3])) < 1.0
    # One node of the patch on the hole is within the default share: it counts against the fill, the truth is found.
    tolerant = run_lost(records, grid_holed, NavParameters())
    assert np.hypot(*(tolerant.mle[3] - truth[3])) < 1.0


def test_leaving_the_map_dead_reckons_flagged_and_counted():
    grid, records, truth = _tow(n=30, start=(300.0, 560.0))  # the map ends at northing 790 m
    result = run_lost(records, grid, NavParameters())
    off = ~grid.contains(*result.predicted.T)
    off[0] = False
    assert off.sum() > 3
    assert np.array_equal(result.off_map, off)
    assert result.counts["off_map"] == off.sum()
    assert np.all(result.mle_source[off] == "")
    assert np.allclose(result.estimate[off], result.predicted[off])


def test_a_missing_velocity_is_held_and_counted():
    grid, records, _ = _tow(n=5)
    vel_y = records.vel_y_mps.copy()
    vel_y[2] = np.nan
    result = run_lost(_replace(records, vel_y_mps=vel_y), grid, NavParameters())
    assert result.counts["velocity_held"] == 1
    assert np.allclose(result.predicted[2], result.estimate[1] + (0.0, 10.0))


def test_a_missing_patch_dead_reckons():
    grid, records, _ = _tow(n=6)
    sonar = list(records.sonar)
    sonar[3] = None
    result = run_lost(_replace(records, sonar=tuple(sonar)), grid, NavParameters())
    assert result.mle_source[3] == ""
    assert np.allclose(result.estimate[3], result.predicted[3])
    assert np.isnan(result.mle[3]).all()


def test_slant_range_corrects_and_gates():
    grid, records, truth = _tow(n=6)
    slant = np.full(6, 480.0)  # the vehicle is 500 m behind the ship: a 20 m correction, over the 15 m gate
    slant[2] = 495.0  # 5 m: applied
    result = run_lost(_replace(records, slant_range_m=slant), grid, NavParameters())
    ship = np.column_stack([records.ship_x_m, records.ship_y_m])
    assert result.slant_corrected[2] and np.hypot(*(result.estimate[2] - ship[2])) == pytest.approx(495.0)
    assert result.counts["slant_range_gated"] == 4  # records 1, 3, 4, 5 (record 0 initializes)
    off = run_lost(_replace(records, slant_range_m=slant), grid, NavParameters(use_slant_range=False))
    assert not off.slant_corrected.any()


def test_point_matching_finds_the_unique_depth():
    rng = np.random.default_rng(9)
    depth = 1000.0 + 0.5 * rng.permutation(80 * 60).reshape(80, 60)  # every depth differs by >= 0.5 m
    grid, records, truth = _tow(n=5, depth_grid=depth)
    floor = np.array([depth[tuple(int(round(v)) for v in grid.row_col(x, y))] for x, y in truth])
    records = _replace(records, vehicle_depth_m=np.full(5, 100.0), altitude_m=floor - 100.0,
                       cable_out_m=np.full(5, np.hypot(500.0, 100.0)))
    result = run_lost(records, grid, NavParameters(matching="point", initial_offset_m=(30.0, 0.0)))
    assert np.all(result.mle_source[1:] == "point")
    assert np.allclose(result.mle[1:], truth[1:])


def test_a_patch_on_other_nodes_is_an_error():
    grid, records, _ = _tow(n=3)
    sonar = tuple(SonarPatch(p.depth_m, 5.0) for p in records.sonar)
    with pytest.raises(ValueError, match="coarser than the sonar patches' 5.0 m"):
        run_lost(_replace(records, sonar=sonar), grid, NavParameters())
    finer = tuple(SonarPatch(p.depth_m, 20.0) for p in records.sonar)
    with pytest.raises(ValueError, match="20.0 m nodes but the map 10.0 m"):
        run_lost(_replace(records, sonar=finer), grid, NavParameters())


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"matching": "bayes"}, "matching"),
        ({"k": -1.0}, "k must be"),
        ({"backend": "fpga-over-smoke"}, "backend"),
        ({"u": 2.0}, "adaptive constant"),
        ({"cross_damping_per_s": -0.05}, "cross-track damping"),
        ({"initial_offset_m": (1.0,)}, "initial_offset_m"),
        ({"min_distinctness": -1.0}, "min_distinctness"),
        ({"layback_model": "guess"}, "layback_model"),
    ],
)
def test_parameters_are_validated(kwargs, message):
    with pytest.raises(ValueError, match=message):
        NavParameters(**kwargs)


def test_patch_matching_without_any_patch_is_an_error():
    grid, records, _ = _tow(n=3)
    with pytest.raises(ValueError, match="no sonar patch"):
        run_lost(_replace(records, sonar=()), grid, NavParameters())


def test_records_before_the_first_ship_fix_wait_uninitialized():
    grid, records, truth = _tow(n=5)
    ship_x = records.ship_x_m.copy()
    ship_x[:2] = np.nan
    result = run_lost(_replace(records, ship_x_m=ship_x), grid, NavParameters())
    assert result.counts["before_initialization"] == 2
    assert np.isnan(result.estimate[:2]).all() and np.allclose(result.estimate[2], truth[2])
