"""The diver/clutter simulator: seeded, its clutter and detection probability as specified, scenarios checked."""

import dataclasses

import numpy as np
import pytest

from lost.host.track.geometry import world_to_polar
from lost.host.track.simulate import builtin_scenario_path, builtin_scenarios, load_scenario, simulate


def test_shipped_scenarios_load():
    assert {"one_diver", "two_divers", "clutter_hour"} <= set(builtin_scenarios())
    for name in builtin_scenarios():
        assert load_scenario(builtin_scenario_path(name)).name == name


def test_same_seed_same_run_other_seed_other_run():
    scenario = load_scenario(builtin_scenario_path("one_diver"))
    a, b = simulate(scenario), simulate(scenario)
    c = simulate(dataclasses.replace(scenario, seed=scenario.seed + 1))
    assert all(np.array_equal(p.range_m, q.range_m) for p, q in zip(a.pings, b.pings))
    assert not all(p.range_m.size == q.range_m.size and np.allclose(p.range_m, q.range_m) for p, q in zip(a.pings, c.pings))


def test_clutter_is_poisson_at_the_stated_rate_and_targets_are_detected_at_pd():
    scenario = load_scenario(builtin_scenario_path("one_diver"))
    scenario = dataclasses.replace(scenario, duration_s=1300.0, sonar=dataclasses.replace(scenario.sonar, clutter_per_ping=8.0, pd=0.7))
    sim = simulate(scenario)
    pings = len(sim.pings)
    assert sim.false_alarms / pings == pytest.approx(8.0, abs=0.3)  # sd of the mean ~0.09
    seen = sim.truth.in_sector[:, 0].sum()
    assert sim.target_detections / seen == pytest.approx(0.7, abs=0.06)
    counts = np.array([p.detections for p in sim.pings])
    assert counts.var() == pytest.approx(8.0 + 0.7 * 0.3, rel=0.2)  # Poisson plus Bernoulli


def test_targets_start_where_the_scenario_puts_them_and_swim_at_the_platform():
    sim = simulate(load_scenario(builtin_scenario_path("two_divers")))
    first = sim.pings[0]
    r, b = world_to_polar(first.platform_xy, first.heading_deg, sim.truth.xy[0])
    np.testing.assert_allclose(r, [420.0, 470.0, 250.0])
    np.testing.assert_allclose(b, [-20.0, 20.0, -40.0])
    np.testing.assert_allclose(np.hypot(*sim.truth.velocity[0].T), [0.6, 0.8, 0.15])
    later = sim.pings[100]
    r_later, _ = world_to_polar(later.platform_xy, later.heading_deg, sim.truth.xy[100, :2])
    assert (r_later < r[:2] - 40).all()  # closing on the sonar
    assert sim.truth.kinds == ("diver", "diver", "drifting")


def test_platform_moves_along_its_heading():
    sim = simulate(load_scenario(builtin_scenario_path("two_divers")))
    step = sim.pings[1].platform_xy - sim.pings[0].platform_xy
    assert np.hypot(*step) == pytest.approx(0.3 * 1.3, rel=1e-3)


@pytest.mark.parametrize(
    "text, message",
    [
        ("[sonar]\npd = 1.5\n", r"pd in \[0, 1\]"),
        ("[sonar]\nclutter = 3\n", r"\[sonar\] has unknown field\(s\) \['clutter'\]"),
        ("[[target]]\nkind = 'whale'\n", "kind must be one of"),
        ("targets = 1\n", r"unknown top-level field\(s\) \['targets'\]"),
        ("name = \n", "is not valid TOML"),
    ],
)
def test_bad_scenarios_are_named(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_scenario(path)
