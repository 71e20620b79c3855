"""Each LOST stage against cases computed by hand from the patent's equations."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from lost import model
from lost.host import correlate
from lost.host.nav import (
    CrossTrackTracker,
    TrackFrame,
    layback_position,
    patch_likelihood,
    point_likelihood,
    refine_minimum,
    slant_range_correct,
    state_update,
)


def test_state_update_is_eq_1():
    # P_p = P_e(t-1) + v dt: (100, 200) + (1.5, -0.5) * 2 s
    assert np.array_equal(state_update(np.array([100.0, 200.0]), np.array([1.5, -0.5]), 2.0), [103.0, 199.0])


def test_state_update_rejects_negative_step():
    with pytest.raises(ValueError, match="non-negative"):
        state_update(np.zeros(2), np.ones(2), -1.0)


def test_track_frame_heading_east():
    frame = TrackFrame(1000.0, 2000.0, 90.0)  # heading east: starboard is south
    assert np.allclose(frame.along_unit, [1.0, 0.0]) and np.allclose(frame.cross_unit, [0.0, -1.0])
    point = np.array([990.0, 2005.0])  # 10 m behind, 5 m to port
    assert math.isclose(frame.along(point), -10.0, abs_tol=1e-12)
    assert math.isclose(frame.cross(point), -5.0, abs_tol=1e-12)
    assert np.allclose(frame.position(-10.0, -5.0), point)


def test_point_likelihood_eq_3_by_hand():
    # dx = 3, dy = 4, dz = 0.5 m, k = 100: 9 + 16 + 100**2 * 0.25
    value = point_likelihood(np.array(3.0), np.array(4.0), 1000.5, np.array(1000.0), k=100.0)
    assert float(value) == 2525.0


def test_point_likelihood_is_eq_2_scaled_by_two_sigma_x_squared():
    rng = np.random.default_rng(1)
    dx, dy, depth = rng.normal(0, 50, 20), rng.normal(0, 50, 20), rng.normal(1000, 5, 20)
    sigma_x, sigma_z = 30.0, 0.3
    eq2 = (dx**2 + dy**2) / (2 * sigma_x**2) + (998.0 - depth) ** 2 / (2 * sigma_z**2)
    ours = point_likelihood(dx, dy, 998.0, depth, k=sigma_x / sigma_z)
    assert np.allclose(ours, 2 * sigma_x**2 * eq2)
    # The ordering, hence the MLE, is eq. 2's.
    assert np.argmin(ours) == np.argmin(eq2)


def test_point_likelihood_holes_never_win():
    value = point_likelihood(np.zeros(3), np.zeros(3), 10.0, np.array([np.nan, 10.0, 50.0]), k=100.0)
    assert value[0] == np.inf and np.argmin(value) == 1


def test_patch_likelihood_by_hand():
    # V = 900 words, n = 10, 0.1 m words, k = 100: 100**2 * (90 m)**2 / 10**3 = 81000, plus 3**2 + 4**2
    value = patch_likelihood(np.array([3.0]), np.array([4.0]), np.array([900]), valid_nodes=10, lsb_m=0.1, k=100.0)
    assert value[0] == pytest.approx(81025.0)


def test_patch_likelihood_equals_sum_of_squares_for_equal_residuals():
    # Residuals of +-r around a common offset: V lsb / n**2 = r exactly, so the term is k**2 * sum r**2.
    terrain = np.arange(16, dtype=np.int16).reshape(4, 4) * 7
    signs = np.array([[1, -1], [-1, 1]])
    r_words, offset_words = 3, 40
    patch = (terrain[1:3, 1:3] + offset_words + r_words * signs).astype(np.int16)
    surface = correlate(terrain, patch)
    lsb, k = 0.05, 100.0
    value = patch_likelihood(np.zeros(1), np.zeros(1), surface[1:2, 1], valid_nodes=4, lsb_m=lsb, k=k)
    assert value[0] == pytest.approx(k**2 * 4 * (r_words * lsb) ** 2)


def test_patch_likelihood_excluded_placements_never_win():
    value = patch_likelihood(np.zeros(2), np.zeros(2), np.array([-1, 5000]), valid_nodes=100, lsb_m=0.1, k=100.0)
    assert value[0] == np.inf and np.isfinite(value[1])


def test_refine_minimum_finds_the_parabola_vertex():
    rows, cols = np.mgrid[0:5, 0:5]
    values = (rows - 2.3) ** 2 + 2 * (cols - 1.8) ** 2
    assert refine_minimum(values, 2, 2) == pytest.approx((2.3, 1.8))
    # On the edge there is no neighbour: the axis stays at the node.
    assert refine_minimum(values, 0, 2)[0] == 0.0


def test_tracker_two_steps_by_hand():
    tracker = CrossTrackTracker(u=0.01, max_accel_mps2=0.05, max_speed_mps=1.0)
    # e = 2, d = 2 u e = 0.04, w = 0.99 * 0 + 0.04 * 1, cross = 0 + w * 1
    assert tracker.update(predicted_cross_m=0.0, mle_cross_m=2.0, dt_s=1.0) == pytest.approx(0.04)
    # e = 1.96, d = 0.0392, w = 0.99 * 0.04 + 0.0392 = 0.0788, cross = 0.04 + 0.0788
    assert tracker.update(predicted_cross_m=0.04, mle_cross_m=2.0, dt_s=1.0) == pytest.approx(0.1188)
    assert tracker.velocity_mps == pytest.approx(0.0788)


def test_tracker_thresholds_acceleration_and_velocity():
    tracker = CrossTrackTracker(u=0.01, max_accel_mps2=0.05, max_speed_mps=1.0)
    # 2 u e = 2 m/s**2 is clipped to 0.05 by f_a.
    assert tracker.update(predicted_cross_m=0.0, mle_cross_m=100.0, dt_s=2.0) == pytest.approx(0.1 * 2.0)
    for _ in range(100):
        tracker.update(predicted_cross_m=0.0, mle_cross_m=100.0, dt_s=2.0)
    assert tracker.velocity_mps == 1.0  # f_v holds it at the threshold
    assert CrossTrackTracker(u=0.01).update(predicted_cross_m=5.0, mle_cross_m=-500.0, dt_s=1.0) == pytest.approx(5.0 - 0.05)


def test_damped_tracker_decays_w_by_its_rate():
    tracker = CrossTrackTracker(u=0.01, max_accel_mps2=0.05, max_speed_mps=1.0, damping_per_s=0.05)
    assert CrossTrackTracker(u=0.01).decay(2.0) == pytest.approx(0.99)  # the patent's, whatever dt
    assert tracker.decay(2.0) == pytest.approx(math.exp(-0.1))
    # e = 2, d = 0.04, w = 0 + 0.04 * 2 = 0.08, cross = 0 + 0.16
    assert tracker.update(predicted_cross_m=0.0, mle_cross_m=2.0, dt_s=2.0) == pytest.approx(0.16)
    # e = 1.84, d = 0.0368, w = exp(-0.1) * 0.08 + 0.0736, cross = 0.16 + 2 w
    w = math.exp(-0.1) * 0.08 + 0.0736
    assert tracker.update(predicted_cross_m=0.16, mle_cross_m=2.0, dt_s=2.0) == pytest.approx(0.16 + 2 * w)
    assert tracker.velocity_mps == pytest.approx(w)


def test_damping_stops_the_patent_trackers_ring():
    # Noise-free, from 3 m off: the patent's tracker still swings past 1 m after 200 s; damped, it has settled.
    def error_after(tracker, seconds):
        cross, errors = 0.0, []
        for _ in range(seconds):
            cross = tracker.update(predicted_cross_m=cross, mle_cross_m=3.0, dt_s=1.0)
            errors.append(abs(cross - 3.0))
        return max(errors[-60:])

    assert error_after(CrossTrackTracker(u=0.01), 200) > 1.0
    assert error_after(CrossTrackTracker(u=0.01, damping_per_s=0.05), 200) < 0.1


@pytest.mark.parametrize("kwargs", [{"u": 0.0}, {"u": 1.0}, {"max_accel_mps2": 0.0}, {"max_speed_mps": -1.0},
                                    {"damping_per_s": -0.1}, {"damping_per_s": float("inf")}, {"damping_per_s": "0.05"}])
def test_tracker_rejects_bad_constants(kwargs):
    with pytest.raises(ValueError):
        CrossTrackTracker(**kwargs)


def test_slant_range_correct_is_eq_8():
    # R_a = 500, R_m = 450: the estimate slides to 0.9 of its vector from the reference point.
    assert np.allclose(slant_range_correct(np.array([300.0, 400.0]), np.zeros(2), 450.0), [270.0, 360.0])
    assert np.allclose(slant_range_correct(np.array([13.0, 14.0, 12.0]), np.array([10.0, 10.0, 0.0]), 26.0), [16.0, 18.0, 24.0])


def test_slant_range_correct_rejects_degenerate_cases():
    with pytest.raises(ValueError, match="reference point"):
        slant_range_correct(np.ones(2), np.ones(2), 10.0)
    with pytest.raises(ValueError, match="measured range"):
        slant_range_correct(np.ones(2), np.zeros(2), float("nan"))


def test_layback_position_behind_the_ship():
    assert np.allclose(layback_position(TrackFrame(100.0, 200.0, 0.0), 50.0), [100.0, 150.0])
    assert np.allclose(layback_position(TrackFrame(0.0, 0.0, 45.0), math.sqrt(2)), [-1.0, -1.0])


def test_patch_likelihood_agrees_with_model_best_fit_without_prior():
    # With no distance term the patch MLE is the correlator's best fit.
    rng = np.random.default_rng(3)
    terrain = rng.integers(-500, 500, (30, 30)).astype(np.int16)
    patch = terrain[11:17, 4:10].copy()
    surface = correlate(terrain, patch)
    value = patch_likelihood(np.zeros(surface.shape), np.zeros(surface.shape), surface, valid_nodes=36, lsb_m=0.1, k=100.0)
    fit = model.best_fit(surface)
    assert np.unravel_index(np.argmin(value), value.shape) == (fit.i, fit.j) == (11, 4)


finite = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)


@given(
    u=st.floats(min_value=1e-4, max_value=0.5),
    max_accel=st.floats(min_value=1e-3, max_value=1.0),
    max_speed=st.floats(min_value=1e-2, max_value=5.0),
    steps=st.lists(st.tuples(finite, finite, st.floats(min_value=0.0, max_value=10.0)), min_size=1, max_size=20),
    damping=st.none() | st.floats(min_value=0.0, max_value=1.0),
)
def test_tracker_never_exceeds_its_thresholds(u, max_accel, max_speed, steps, damping):
    tracker = CrossTrackTracker(u=u, max_accel_mps2=max_accel, max_speed_mps=max_speed, damping_per_s=damping)
    for predicted, mle, dt in steps:
        before = tracker.velocity_mps
        cross = tracker.update(predicted_cross_m=predicted, mle_cross_m=mle, dt_s=dt)
        assert abs(tracker.velocity_mps) <= max_speed
        # f_a bounds the change beyond the (1 - u) decay; f_v can only pull it further toward zero.
        assert abs(tracker.velocity_mps - tracker.decay(dt) * before) <= max_accel * dt + 1e-9 or abs(tracker.velocity_mps) == max_speed
        assert cross == pytest.approx(predicted + tracker.velocity_mps * dt)
    # From rest, the first correction moves toward the MLE, never away from it.
    fresh = CrossTrackTracker(u=u, max_accel_mps2=max_accel, max_speed_mps=max_speed, damping_per_s=damping)
    predicted, mle, dt = steps[0]
    assert (fresh.update(predicted_cross_m=predicted, mle_cross_m=mle, dt_s=dt) - predicted) * (mle - predicted) >= 0


@given(
    position=st.tuples(finite, finite, finite),
    reference=st.tuples(finite, finite, finite),
    measured=st.floats(min_value=0.0, max_value=1e4),
)
def test_slant_range_correction_lands_on_the_measured_range_along_the_same_ray(position, reference, measured):
    position, reference = np.array(position), np.array(reference)
    distance = np.linalg.norm(position - reference)
    if distance < 1e-3:
        return
    corrected = slant_range_correct(position, reference, measured)
    assert np.linalg.norm(corrected - reference) == pytest.approx(measured, rel=1e-9, abs=1e-6)
    if measured > 0:
        assert np.allclose(np.cross(corrected - reference, position - reference), 0.0, atol=1e-6 * max(distance, measured) ** 2)
