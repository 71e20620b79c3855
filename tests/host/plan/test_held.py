"""The error of a held lock: the map's error against the sonar's patch (a binned swath against a point-sampled patch), one
patch's bound of it rather than the filters' density, and its growth where there is no fix."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from lost.host.grid import Grid
from lost.host.nav.maperror import node_variance
from lost.host.plan import RouteModel, SonarModel, accuracy_grid, held_grid, held_sigma, predict_along


def _plane_with_layer(spread: float = 0.0) -> Grid:
    """A tilted plane whose sigma layer is its soundings' spread in a cell: the plane's own (slope * L / sqrt(12) an
    axis) plus ``spread`` of independent noise."""
    rows, cols = np.mgrid[0:30, 0:40]
    node = 20.0
    depth = 800.0 + 0.2 * cols * node + 0.1 * rows * node
    plane = node_variance(depth, node, 0.0)
    return Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=node, sigma_m=np.sqrt(plane + spread**2))


def test_a_binned_swath_sees_the_surveys_common_error_a_point_sampled_patch_the_whole_spread():
    for spread in (0.3, 3.0):  # the spread averages out of the node's mean and the binned patch's alike
        grid = _plane_with_layer(spread=spread)
        binned = held_sigma(grid, SonarModel(binned=True), 0.2)
        points = held_sigma(grid, SonarModel(binned=False), 0.2)
        inside = (slice(2, -2), slice(2, -2))  # the plane's second differences are exact away from the edges: no relief
        assert np.allclose(binned[inside], 0.2, atol=1e-9)
        assert np.allclose(points, grid.sigma_m)
        assert np.all(points[inside] > 3 * binned[inside])


def _sandwich_written_out(grid: Grid, sonar: SonarModel, weight_sigma: np.ndarray, error_sigma: np.ndarray, row: int, col: int) -> float:
    """The weighted least-squares fit of (shift east, shift north, depth offset) over the patch centred at (row, col), its
    covariance A^-1 B A^-1 written out with the offset as a third unknown, the trace of its shift block."""
    h, w = sonar.shape
    window = (slice(row - h // 2, row - h // 2 + h), slice(col - w // 2, col - w // 2 + w))
    gy, gx = np.gradient(grid.depth_m, grid.node_m)
    design = np.column_stack([gx[window].ravel(), gy[window].ravel(), np.ones(h * w)])
    weight = 1.0 / (sonar.noise_m**2 + weight_sigma[window].ravel() ** 2)
    variance = sonar.node_noise_m**2 + error_sigma[window].ravel() ** 2
    a = design.T @ (weight[:, None] * design)
    b = design.T @ ((weight**2 * variance)[:, None] * design)
    inverse = np.linalg.inv(a)
    return float(np.sqrt(np.trace((inverse @ b @ inverse)[:2, :2])))


def test_the_held_bound_of_mismatched_weights_is_the_sandwich_written_out():
    rng = np.random.default_rng(8)
    depth = 500.0 + 40.0 * ndimage.gaussian_filter(rng.normal(size=(40, 50)), 2.0)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(shape=(6, 8), noise_m=0.3)
    weights, errors = 0.2 + 2.0 * rng.random(depth.shape), 0.1 + 0.5 * rng.random(depth.shape)
    held = held_grid(grid, sonar, weights, errors).depth_m
    for row, col in ((10, 12), (20, 25), (30, 40)):
        assert held[row, col] == pytest.approx(_sandwich_written_out(grid, sonar, weights, errors, row, col), rel=1e-8)
    optimal = accuracy_grid(grid, sonar, errors).depth_m  # weights the errors' own: the bound, the least of all weightings
    ok = np.isfinite(optimal)
    assert np.array_equal(np.isfinite(held), ok)
    assert np.allclose(held_grid(grid, sonar, errors, errors).depth_m[ok], optimal[ok], rtol=1e-9)
    assert np.all(held[ok] >= optimal[ok] * (1 - 1e-9)) and np.median(held[ok] / optimal[ok]) > 1.05


def test_a_map_without_a_layer_takes_the_survey_sigma_and_the_relief():
    depth = 500.0 + 30.0 * ndimage.gaussian_filter(np.random.default_rng(3).normal(size=(40, 50)), 2.0)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    held = held_sigma(grid, SonarModel(), 0.4)
    full = node_variance(depth, 10.0, 0.4)
    assert np.all(held >= 0.4 - 1e-12) and np.all(held**2 <= full + 1e-9)
    assert np.any(held**2 < full - 1e-3)  # the slope term is the filters' allowance, not the held error


def test_the_held_error_is_one_patchs_bound_below_the_density_floor_and_grows_through_a_hole():
    bound = np.full((40, 200), 1.0)
    bound[:, 80:140] = np.inf  # no fix here
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    held = Grid(depth_m=np.where(np.isfinite(bound), 0.6, np.inf), x0_m=0.0, y0_m=0.0, node_m=10.0)
    model = RouteModel(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=0.2, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=3.0)
    t = np.arange(0.0, 990.0)
    xy = np.column_stack([2.0 * t, np.full(t.size, 200.0)])
    density = predict_along(accuracy, t, xy, model)
    route = predict_along(accuracy, t, xy, model, held=held)
    column = np.rint(route["east_m"] / 10.0)
    blind = (column >= 80) & (column < 140)
    assert np.allclose(route["predicted_m"][(column > 5) & (column < 80)], 0.6)  # not the floor's 3 m: that is the density's width
    assert np.all(density["predicted_m"] >= 3.0 - 1e-12)
    grown = route["predicted_m"][blind]
    assert np.all(np.diff(grown) > 0) and grown[-1] > 2 * 0.6
    # it grows as the density does from the last fix: the same increase of the mean square
    assert grown[-1] ** 2 - 0.6**2 == pytest.approx(density["predicted_m"][blind][-1] ** 2 - density["predicted_m"][np.flatnonzero(blind)[0] - 1] ** 2,
                                                    rel=1e-6)
    # with a slant range holding the axis along it, the error held grows across it alone: half the mean square
    ranged = predict_along(accuracy, t, xy, RouteModel(**{**model.__dict__, "slant_range": True}), held=held)["predicted_m"][blind]
    assert ranged[-1] ** 2 - 0.6**2 == pytest.approx(0.5 * (grown[-1] ** 2 - 0.6**2), rel=1e-6)


def test_after_a_hole_the_error_held_returns_to_the_patchs_by_each_updates_gain():
    bound = np.full((40, 200), 1.0)
    bound[:, 80:140] = np.inf
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    held = Grid(depth_m=np.where(np.isfinite(bound), 0.6, np.inf), x0_m=0.0, y0_m=0.0, node_m=10.0)
    model = RouteModel(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=0.2, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=0.5,
                       patch_length_m=40.0)
    t = np.arange(0.0, 990.0)
    xy = np.column_stack([2.0 * t, np.full(t.size, 200.0)])
    error = predict_along(accuracy, t, xy, model, held=held)["predicted_m"]
    back = np.flatnonzero(np.rint(xy[:, 0] / 10.0) >= 140)
    grown, first = error[back[0] - 1], error[back[0]]
    # the first fix after the hole weighs the whole patch against a density grown wide: most of the way, not all
    assert 0.6 < first < 0.6 + 0.5 * (grown - 0.6)
    excess = error[back[:60]] - 0.6
    assert np.all(np.diff(excess) < 0) and excess[-1] < 0.05 * excess[0]  # each later fix takes its gain of what is left
    # at a steady density the gain is steady: the excess decays geometrically
    ratios = excess[40:] / excess[39:-1]
    assert np.all(ratios < 1.0) and np.ptp(ratios) < 0.01


def test_a_binned_node_averages_its_soundings_noise_out_of_the_held_error():
    rng = np.random.default_rng(9)
    depth = 500.0 + 40.0 * ndimage.gaussian_filter(rng.normal(size=(40, 50)), 2.0)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    weights, errors = np.full(depth.shape, 0.8), np.full(depth.shape, 0.2)
    single, averaged = SonarModel(shape=(6, 8), noise_m=0.5), SonarModel(shape=(6, 8), noise_m=0.5, soundings_per_node=100.0)
    assert averaged.node_noise_m == pytest.approx(0.05)
    assert SonarModel(noise_m=0.5, binned=False, soundings_per_node=100.0).node_noise_m == 0.5  # a sampled node is one sounding
    fewer, more = held_grid(grid, single, weights, errors).depth_m, held_grid(grid, averaged, weights, errors).depth_m
    ok = np.isfinite(fewer)
    assert ok.any() and np.all(more[ok] < 0.7 * fewer[ok])  # 0.5 m of noise of 0.54 m in all, to 0.05 m of 0.21 m
    assert more[20, 25] == pytest.approx(_sandwich_written_out(grid, averaged, weights, errors, 20, 25), rel=1e-8)
    # the weights stay the filters': the bound does not move
    assert np.array_equal(accuracy_grid(grid, single, weights).depth_m, accuracy_grid(grid, averaged, weights).depth_m)
    with pytest.raises(ValueError, match="at least one sounding"):
        SonarModel(soundings_per_node=0.5)


def test_a_scenarios_swath_node_averages_its_beams_across_and_pings_along():
    from lost.host.cli.plan import scenario_sonar
    from lost.host.scenario import builtin_scenario_path, load_scenario

    demo = load_scenario(builtin_scenario_path("demo"))  # 64 beams over 300 m, a ping a second at 3 kn, 10 % without a return
    sonar = scenario_sonar(demo, 30.0)
    assert sonar.soundings_per_node == pytest.approx(64 * 30 / 300 * 30 / (3 * 1852 / 3600) * 0.9)
    assert sonar.binned and sonar.realtime and sonar.noise_m == 0.3 and sonar.shape == (10, 10)
    short = load_scenario(builtin_scenario_path("short"))  # a patch sampled at points: a sounding a node
    assert scenario_sonar(short, 30.0).node_noise_m == short.sensors["sonar"].noise


def test_the_held_bound_on_rough_ground_is_below_the_filters_bound():
    depth = 500.0 + 40.0 * ndimage.gaussian_filter(np.random.default_rng(5).normal(size=(50, 60)), 2.0)
    grid = Grid(depth_m=depth, x0_m=0.0, y0_m=0.0, node_m=10.0)
    sonar = SonarModel(noise_m=0.3)
    filters = accuracy_grid(grid, sonar, np.sqrt(node_variance(depth, 10.0, 0.5))).depth_m
    held = accuracy_grid(grid, sonar, held_sigma(grid, sonar, 0.5)).depth_m
    ok = np.isfinite(filters)
    assert ok.any() and np.all(held[ok] <= filters[ok] + 1e-12)


def test_a_real_time_patch_is_centred_half_its_diagonal_behind_and_its_fixes_lag_so():
    assert SonarModel(shape=(8, 8), realtime=True).lag_m(40.0) == pytest.approx(np.hypot(8, 8) * 20.0)
    assert SonarModel(shape=(8, 8)).lag_m(40.0) == 0.0
    bound = np.full((40, 300), 1.0)
    bound[:, 100:150] = np.inf  # no fix from 1000 to 1500 m
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    t = np.arange(0.0, 1400.0)
    xy = np.column_stack([2.0 * t, np.full(t.size, 200.0)])
    model = RouteModel(speed_mps=2.0, interval_s=1.0, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=1.0)
    at_vehicle = predict_along(accuracy, t, xy, model)
    behind = predict_along(accuracy, t, xy, RouteModel(**{**model.__dict__, "patch_lag_m": 300.0}))
    def changes(route):  # where the fixes stop and where they resume, metres east
        return route["east_m"][1:][np.diff(route["usable"].astype(int)) != 0]

    assert changes(at_vehicle) == pytest.approx([995.0, 1495.0], abs=6.0)
    assert changes(behind)[1:] - changes(at_vehicle) == pytest.approx([300.0, 300.0], abs=2.0)
    # before it has gone 300 m, the patch lies about its first pings, and it fills over its first patch length (100 m):
    # its bound that much wider, no fix before a twenty-fifth of it (a 1 m bound against the usable 5 m)
    assert changes(behind)[0] == pytest.approx(4.0, abs=2.0) and not behind["usable"][0] and behind["usable"][3:500].all()
    assert behind["bound_m"][25] == pytest.approx(1.0 / np.sqrt(0.5)) and behind["bound_m"][50] == pytest.approx(1.0)
    assert at_vehicle["bound_m"][0] == 1.0  # a patch that is not real-time is whole from the start
    with pytest.raises(ValueError, match="patch_lag_m"):
        RouteModel(patch_lag_m=-1.0)


def test_without_a_fix_the_density_widens_by_the_velocity_bias_not_yet_learned():
    from lost.host.nav.trust import ins_position_sigma

    bound = np.full((40, 600), 1.0)
    bound[:, 20:80] = np.inf  # an early stretch without a fix, and the same stretch late
    bound[:, 500:560] = np.inf
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    t = np.arange(0.0, 2900.0)
    xy = np.column_stack([2.0 * t, np.full(t.size, 200.0)])
    base = dict(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=0.01, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=1.0)
    never_learned = predict_along(accuracy, t, xy, RouteModel(**base, velocity_bias_sigma_mps=0.05, bias_learning_updates=10**9))
    blind = ~never_learned["usable"] & (t > 50.0) & (t < 1000.0)
    since = t[blind] - t[np.flatnonzero(blind)[0] - 1]
    ins = ins_position_sigma(since, gyro_bias_rps=RouteModel.gyro_bias_rps, accel_bias_mps2=RouteModel.accel_bias_mps2)
    p_fix = 0.5  # the floor, half an axis of 1 m
    by_hand = 2.0 * (p_fix + 0.01**2 * since * 1.0 + ins**2 + 0.05**2 * since**2)
    assert never_learned["predicted_m"][blind] ** 2 == pytest.approx(by_hand, rel=1e-9)
    learned = predict_along(accuracy, t, xy, RouteModel(**base, velocity_bias_sigma_mps=0.05, velocity_bias_walk_mps=0.0005))
    none = predict_along(accuracy, t, xy, RouteModel(**base))
    early, late = (t > 370.0) & (t < 398.0), (t > 2770.0) & (t < 2798.0)  # the end of each stretch
    end = {name: (route["predicted_m"][early].max(), route["predicted_m"][late].max())
           for name, route in (("never", never_learned), ("learned", learned), ("none", none))}
    assert end["never"][0] > 1.8 * end["learned"][0] and end["learned"][0] > 1.4 * end["none"][0]  # learned from a hundred fixes only
    assert end["none"][1] < end["learned"][1] < 0.85 * end["learned"][0]  # and better learned later


def _gap_route(**fields) -> dict:
    """Along a uniform map (bound 1 m, held 0.5 m) with 300 s without a fix after 100 s of fixes."""
    bound = np.full((40, 600), 1.0)
    bound[:, 20:80] = np.inf
    held = np.where(np.isfinite(bound), 0.5, np.inf)
    accuracy = Grid(depth_m=bound, x0_m=0.0, y0_m=0.0, node_m=10.0)
    t = np.arange(0.0, 500.0)
    xy = np.column_stack([2.0 * t, np.full(t.size, 200.0)])
    base = dict(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=0.01, initial_sigma_m=100.0, usable_sigma_m=5.0, floor_m=1.0,
                gyro_bias_rps=0.0, accel_bias_mps2=0.0)  # a DVL's dead reckoning alone
    route = predict_along(accuracy, t, xy, RouteModel(**{**base, **fields}), held=Grid(depth_m=held, x0_m=0.0, y0_m=0.0, node_m=10.0))
    return {**route, "t": t}


def test_the_error_held_grows_by_the_sensors_own_errors_where_they_are_known():
    never = dict(velocity_bias_sigma_mps=0.05, bias_learning_updates=10**9)  # the filters never learn their bias
    known = _gap_route(**never, sensor_velocity_noise_mps=0.02, sensor_velocity_bias_mps=(0.01, -0.005))
    assumed = _gap_route(**never)
    blind = ~known["usable"] & (known["t"] < 400.0)
    since = known["t"][blind] - known["t"][np.flatnonzero(blind)[0] - 1]
    # the whole bias is left (nothing learned): the one patch's bound grown by the sensor's noise and its bias
    by_hand = 0.5**2 + 2.0 * 0.02**2 * since + (0.01**2 + 0.005**2) * since**2
    assert known["predicted_m"][blind] ** 2 == pytest.approx(np.minimum(by_hand, assumed["predicted_m"][blind] ** 2), rel=1e-9)
    assert known["predicted_m"][blind][-1] < 0.3 * assumed["predicted_m"][blind][-1]  # 0.011 m/s against the prior's 0.05
    # a bias as large as the filters' prior, learned: what a consistent filter holds, k^2 b^2 + P (1 - k) = P
    learned = dict(velocity_bias_sigma_mps=0.05, velocity_bias_walk_mps=0.0005)
    consistent = _gap_route(**learned, sensor_velocity_noise_mps=0.01, sensor_velocity_bias_mps=(0.05, 0.05))
    smaller = _gap_route(**learned, sensor_velocity_noise_mps=0.01, sensor_velocity_bias_mps=(0.0, 0.0))
    assert consistent["predicted_m"][blind] == pytest.approx(_gap_route(**learned)["predicted_m"][blind], rel=1e-9)
    assert smaller["predicted_m"][blind][-1] < 0.95 * consistent["predicted_m"][blind][-1]
    assert np.all(smaller["predicted_m"][blind] <= consistent["predicted_m"][blind] + 1e-12)


def test_while_the_search_goes_on_the_estimate_shows_the_starts_error():
    from lost.host.plan import Lookalike

    accuracy = Grid(depth_m=np.full((40, 400), np.inf), x0_m=0.0, y0_m=0.0, node_m=10.0)  # the route runs beside this map
    edges = np.array([40.0, 80.0])
    unknown = np.full((2, 40, 400), np.nan)
    lookalike = Lookalike(ring_edges_m=edges, snr=unknown, distance_m=unknown, rivals=unknown, evidence_scale=32.0)
    t = np.arange(0.0, 200.0)
    xy = np.column_stack([100.0 + 2.0 * t, np.full(t.size, 1000.0)])
    base = dict(speed_mps=2.0, interval_s=1.0, velocity_noise_mps=1e-6, initial_sigma_m=300.0, usable_sigma_m=5.0, floor_m=1.0)
    prior = predict_along(accuracy, t, xy, RouteModel(**base), lookalike)
    start = predict_along(accuracy, t, xy, RouteModel(**base, initial_error_m=180.0), lookalike)
    assert prior["unlocked"].min() > 1.0 - 1e-9 and start["unlocked"].min() > 1.0 - 1e-9
    assert prior["predicted_m"] == pytest.approx(np.sqrt(2.0) * 300.0, rel=1e-6)
    assert start["predicted_m"] == pytest.approx(180.0, rel=1e-6)


@pytest.mark.parametrize("field, bad", [("sensor_velocity_noise_mps", -0.1), ("sensor_velocity_noise_mps", float("nan")),
                                        ("sensor_velocity_bias_mps", (0.1,)), ("sensor_velocity_bias_mps", (0.1, float("inf"))),
                                        ("initial_error_m", -5.0)])
def test_the_sensors_errors_and_the_starts_are_checked(field, bad):
    with pytest.raises(ValueError, match=field):
        RouteModel(**{field: bad})
