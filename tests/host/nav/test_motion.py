"""A patch gridded again with each sounding placed by its own age (lost.host.nav.motion), and its soundings as carried."""

from collections import Counter
from dataclasses import replace

import numpy as np

from lost.host.io.sonar import grid_soundings
from lost.host.nav.estimator import Estimate
from lost.host.nav.motion import compensated, record_bias
from lost.host.records import SoundingArrays

NODE_M = 10.0


def _swept_soundings(bias: np.ndarray) -> tuple[np.ndarray, ...]:
    """A minute of pings of a vehicle going east at 2 m/s, 20 beams across, on a rough floor: each sounding's true offset
    from the vehicle at the record, and the offset dead reckoning with ``bias`` gives it (b * age short)."""
    rng = np.random.default_rng(5)
    age = np.repeat(np.arange(60.0), 20)
    across = np.tile(np.linspace(-40.0, 40.0, 20), 60) + rng.uniform(-0.5, 0.5, age.size)
    true_east, true_north = -2.0 * age + rng.uniform(-0.5, 0.5, age.size), across
    depth = 100.0 + 5.0 * np.sin(true_east / 13.0) * np.cos(true_north / 9.0)
    return true_east, true_north, depth, age, true_east - bias[0] * age, true_north - bias[1] * age


def test_a_patch_placed_by_the_true_bias_is_the_truth_placed_patch_moved_by_the_bias_times_its_mean_age():
    bias = np.array([0.2, -0.15])
    true_east, true_north, depth, age, east, north = _swept_soundings(bias)
    centre = (-60.0, 0.0)
    reckoned = grid_soundings(east, north, depth, patch_shape=(9, 14), node_m=NODE_M, centre_m=centre, age_s=age,
                              soundings=SoundingArrays(east, north, depth, age)).patch
    placed = compensated(reckoned, bias)
    mean_age = reckoned.age_s
    # Each sounding moved by b (a - mean age): where the truth puts it, less the one shift b * mean age each filter applies.
    expected = grid_soundings(true_east - bias[0] * mean_age, true_north - bias[1] * mean_age, depth, patch_shape=(9, 14),
                              node_m=NODE_M, centre_m=centre, age_s=age).patch
    np.testing.assert_allclose(placed.depth_m, expected.depth_m, rtol=0, atol=1e-9)
    assert placed.centre_offset_m == reckoned.centre_offset_m
    # It carries its soundings as placed, so that a grid of them on a moved lattice is placed alike.
    placed_east, placed_north, _, placed_age = placed.soundings.arrays()
    np.testing.assert_allclose(placed_east, east + bias[0] * (age - mean_age), rtol=0, atol=1e-12)
    np.testing.assert_allclose(placed_north, north + bias[1] * (age - mean_age), rtol=0, atol=1e-12)
    assert np.array_equal(placed_age, age)
    # The reckoned patch is another one: a 12 m stretch along the track moves soundings across nodes.
    assert np.nanmax(np.abs(reckoned.depth_m - expected.depth_m)) > 0.5


def test_a_patch_without_soundings_a_zero_or_unknown_bias_or_a_move_under_a_fiftieth_of_a_node_is_used_as_it_is():
    bias = np.array([0.1, 0.0])
    _, _, depth, age, east, north = _swept_soundings(bias)
    carried = grid_soundings(east, north, depth, patch_shape=(9, 14), node_m=NODE_M, centre_m=(-60.0, 0.0), age_s=age,
                             soundings=SoundingArrays(east, north, depth, age)).patch
    bare = replace(carried, soundings=None)
    assert compensated(bare, bias) is bare
    assert compensated(carried, np.zeros(2)) is carried
    assert compensated(carried, np.array([np.nan, 0.1])) is carried
    assert compensated(carried, np.array([0.19 / 30.0, 0.0])) is carried  # at most 0.19 m over +-30 s: under 0.2 m
    assert compensated(carried, np.array([0.21 / 30.0, 0.0])) is not carried


def _answer(usable: bool, bias, sigma) -> Estimate:
    return Estimate(position=np.zeros(2), covariance=np.eye(2), usable=usable, stage="tracking", velocity_bias_mps=bias,
                    velocity_bias_sigma_mps=sigma)


def test_the_record_bias_is_the_usable_answers_with_the_smallest_sigma_and_zero_without_one():
    nan = (float("nan"), float("nan"))
    answers = [_answer(True, (0.3, 0.1), (0.05, 0.04)), _answer(False, (0.9, 0.9), (0.001, 0.001)),
               _answer(True, (0.2, 0.0), (0.02, 0.03)), _answer(True, nan, nan)]
    np.testing.assert_array_equal(record_bias(answers), [0.2, 0.0])
    np.testing.assert_array_equal(record_bias(answers[1:2] + answers[3:]), [0.0, 0.0])
    np.testing.assert_array_equal(record_bias([]), [0.0, 0.0])


def test_a_swath_scenarios_patches_carry_the_soundings_they_were_gridded_from():
    from lost.host.scenario import simulate
    from lost.host.scenario.spec import Scenario, SonarSpec

    scenario = Scenario(duration_s=120.0, sensors={"sonar": SonarSpec(mode="swath", realtime=True, beams=32, shape=(6, 6), interval_s=5.0)})
    _, records = simulate(scenario)
    patches = [p for p in records.sonar if p is not None]
    assert len(patches) >= 20
    for patch in patches:
        east, north, depth, age = patch.soundings.arrays()
        again = grid_soundings(east, north, depth, patch_shape=patch.depth_m.shape, node_m=patch.node_m, centre_m=patch.centre_offset_m,
                               age_s=age).patch
        np.testing.assert_array_equal(again.depth_m, patch.depth_m)
        assert again.age_s == patch.age_s and np.all(age >= 0)


class _Reporting:
    """An estimator that keeps the patches it is given and reports a usable estimate with a known velocity bias."""

    name = "fixed_bias"

    def __init__(self, bias) -> None:
        self.counts, self.bias, self.patches = Counter(), bias, []

    def start(self, t_s, position, observation) -> None:
        self.position = np.asarray(position, float)

    def predict(self, motion) -> None:
        pass

    def update(self, observation) -> None:
        self.patches.append(observation.patch)

    def estimate(self) -> Estimate:
        return Estimate(position=self.position, covariance=np.eye(2), usable=True, stage="tracking", velocity_bias_mps=self.bias,
                        velocity_bias_sigma_mps=(0.01, 0.01))


def _loop_patches(records, params) -> tuple[list, Counter]:
    from lost.host.nav.loop import RecordLoop

    estimator, counts = _Reporting((0.3, -0.2)), Counter()
    loop = RecordLoop(records, params, [estimator], counts)
    for n in range(len(records)):
        loop.step(n)
    return estimator.patches, counts


def test_the_loop_hands_every_estimator_the_patch_placed_by_the_bias_of_the_record_before():
    from lost.host.nav import NavParameters
    from lost.host.scenario import simulate
    from lost.host.scenario.spec import Scenario, SonarSpec

    scenario = Scenario(duration_s=300.0, sensors={"sonar": SonarSpec(mode="swath", realtime=True, beams=32, shape=(6, 6), interval_s=5.0)})
    _, records = simulate(scenario)
    params = NavParameters(**scenario.navigation)
    patches, counts = _loop_patches(records, params)
    given = [p for p in patches if p is not None]
    reckoned = [p for p in records.sonar[1:] if p is not None]
    sounded = sum(p.soundings.arrays()[3].size > 0 for p in reckoned)  # the first patches of the tow hold no sounding
    assert len(given) == len(reckoned) and sounded >= 30 and counts["patches_placed_by_age"] == sounded
    for placed, patch in zip(given, reckoned):
        np.testing.assert_array_equal(placed.depth_m, compensated(patch, np.array([0.3, -0.2])).depth_m)
    assert sum(not np.array_equal(a.depth_m, b.depth_m, equal_nan=True) for a, b in zip(given, reckoned)) >= sounded // 2
    patches, counts = _loop_patches(records, replace(params, compensate_patch_motion=False))
    assert [p for p in patches if p is not None] == reckoned and counts["patches_placed_by_age"] == 0
