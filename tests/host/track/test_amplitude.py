"""Detection strength as evidence: the amplitude ratio by hand, the simulator's strengths against scipy's laws (not the
tracker's Gaussians), and a strong return confirming sooner than a weak one."""

import math

import numpy as np
import pytest
from scipy import stats

from lost.host.track import Ping, Sonar
from lost.host.track.amplitude import amplitude_ratio, check_strength_scale
from lost.host.track.simulate import SonarModel, clutter_strength_db, strength_moments, target_strength_db
from lost.host.track.tracker import MultiTargetTracker, TrackerParameters


def test_the_ratio_is_the_two_gaussians_by_hand_clipped_and_one_where_unknown():
    p = TrackerParameters()
    s = np.array([p.target_strength_db, 5.0, 0.0, 40.0, np.nan])
    expected = stats.norm.pdf(s, p.target_strength_db, p.target_strength_sigma_db) / stats.norm.pdf(s, p.clutter_strength_db, p.clutter_strength_sigma_db)
    ratio = amplitude_ratio(s, p)
    np.testing.assert_allclose(ratio[:3], expected[:3], rtol=1e-12)
    assert ratio[3] == pytest.approx(p.max_amplitude_ratio)  # far in the tails the Gaussian fit is not trusted
    assert ratio[4] == 1.0  # no strength: no evidence
    assert ratio[0] > 10 and ratio[2] < 0.2
    np.testing.assert_array_equal(amplitude_ratio(s, TrackerParameters(amplitude=False)), np.ones(5))


def test_the_simulators_strengths_follow_swerling_and_generalized_pareto_laws():
    rng = np.random.default_rng(5)
    pd = 0.9
    power = 10 ** (target_strength_db(pd, 200_000, rng) / 10) - 1  # over the threshold
    assert stats.kstest(power, stats.expon(scale=-1 / math.log(pd)).cdf).pvalue > 1e-3
    excess = 10 ** (clutter_strength_db(0.4, 0.6, 200_000, rng) / 10) - 1
    assert stats.kstest(excess, stats.genpareto(c=0.4, scale=0.6).cdf).pvalue > 1e-3
    # The tracker's Gaussian in dB is not the truth: the clutter's tail beyond three of its sigmas is far heavier.
    m = strength_moments(SonarModel())
    clutter_db = 10 * np.log10(1 + excess)
    assert np.mean(clutter_db > m["clutter_strength_db"] + 3 * m["clutter_strength_sigma_db"]) > 5 * stats.norm.sf(3)
    # A weaker target (lower pd) is weaker in strength too.
    assert strength_moments(SonarModel(pd=0.6))["target_strength_db"] < m["target_strength_db"] - 3


def _existence_after(strength_db: float, pings: int = 4, **settings) -> list[float]:
    tracker = MultiTargetTracker(sonar=Sonar(), parameters=TrackerParameters(particles=2000, **settings), rng=np.random.default_rng(0))
    existence = []
    for i in range(pings):
        reports = tracker.step(Ping(i, 1.3 * i, (0.0, 0.0), 0.0, [300.0], [5.0], [strength_db]))
        existence.append(reports[0].existence if reports else math.nan)
    return existence


def _first_update(existence: list[float]) -> tuple[int, float]:
    """The ping a track was born at and the factor its first update multiplied its odds of existence by."""
    born = next(i for i, r in enumerate(existence) if not math.isnan(r))
    odds = [r / (1 - r) for r in existence[born: born + 2]]
    return born, odds[1] / odds[0]


def test_a_strong_return_is_born_sooner_and_raises_existence_faster_than_a_weak_one_and_than_none():
    (born_strong, strong), (born_weak, weak), (born_unknown, unknown) = (
        _first_update(_existence_after(s)) for s in (14.0, 1.0, math.nan))
    assert born_strong < born_unknown < born_weak  # the search cloud gathers on strong returns first
    assert strong / unknown == pytest.approx(TrackerParameters().max_amplitude_ratio, rel=0.01)  # 14 dB is at the clip
    assert weak < unknown
    assert _existence_after(14.0, amplitude=False) == pytest.approx(_existence_after(math.nan), nan_ok=True)


def test_a_log_without_strengths_or_with_few_is_not_judged_on_their_scale():
    quiet = [Ping(i, 1.3 * i, (0.0, 0.0), 0.0, [300.0], [5.0]) for i in range(30)]
    check_strength_scale(quiet, TrackerParameters())
    few = [Ping(i, 1.3 * i, (0.0, 0.0), 0.0, [300.0], [5.0], [150.0]) for i in range(10)]
    check_strength_scale(few, TrackerParameters())
