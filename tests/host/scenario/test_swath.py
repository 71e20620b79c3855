"""The swath's soundings: taken ping by ping (a slice for a run of consecutive pings), handed out without changing a record."""

from dataclasses import fields, replace

import numpy as np
import pytest

from lost.host.scenario import builtin_scenario_path, load_scenario, simulate
from lost.host.scenario.swath import _SoundedBeams
from lost.host.scenario.tow import simulate_with_swath


def test_the_soundings_of_any_pings_are_those_a_mask_over_their_beams_takes_in_the_same_order():
    rng = np.random.default_rng(3)
    depth = rng.normal(100.0, 1.0, (30, 8))
    depth[rng.random(depth.shape) < 0.3] = np.nan
    depth[7] = np.nan  # a ping with no return at all
    offsets = rng.normal(0.0, 50.0, (30, 8, 2))
    beams = _SoundedBeams(depth, offsets)
    for pings in (np.arange(5, 12), np.array([2, 3, 9, 10, 11, 20]), np.array([7]), np.array([], dtype=np.int64), np.arange(30)):
        east, north, sounded_depth, ping = beams.of(pings)
        sounded = np.isfinite(depth[pings])
        np.testing.assert_array_equal(east, offsets[pings][..., 0][sounded])
        np.testing.assert_array_equal(north, offsets[pings][..., 1][sounded])
        np.testing.assert_array_equal(sounded_depth, depth[pings][sounded])
        np.testing.assert_array_equal(ping, np.broadcast_to(pings[:, None], sounded.shape)[sounded])


def _assert_same_records(a, b, name: str) -> None:
    for f in fields(a):
        if f.name == "sonar":
            assert len(a.sonar) == len(b.sonar), name
            for p, q in zip(a.sonar, b.sonar):
                assert (p is None) == (q is None), name
                if p is not None:
                    np.testing.assert_array_equal(p.depth_m, q.depth_m, err_msg=name)
                    assert (p.node_m, p.centre_offset_m, p.age_s) == (q.node_m, q.centre_offset_m, q.age_s), name
                    assert (p.soundings is None) == (q.soundings is None), name
                    if p.soundings is not None:
                        for x, y in zip(p.soundings.arrays(), q.soundings.arrays()):
                            np.testing.assert_array_equal(x, y, err_msg=name)
        elif getattr(a, f.name) is not None or getattr(b, f.name) is not None:
            np.testing.assert_array_equal(getattr(a, f.name), getattr(b, f.name), err_msg=f"{name}: {f.name}")


def test_a_scenarios_records_are_the_same_whether_its_swath_is_handed_out_or_not():
    # A real-time swath, a swath with a USBL's draws after it, a gridded sonar: one code path each (every shipped one is
    # one of these; their floors take seconds each to make).
    for name in ("demo", "usbl_nav", "short"):
        scenario = load_scenario(builtin_scenario_path(name))
        scenario = replace(scenario, duration_s=min(scenario.duration_s, 60))
        grid, records, swath = simulate_with_swath(scenario)
        plain_grid, plain = simulate(scenario)
        np.testing.assert_array_equal(grid.depth_m, plain_grid.depth_m, err_msg=name)
        _assert_same_records(records, plain, name)
        assert (swath is None) == (scenario.sensors["sonar"].mode != "swath"), name


def test_the_swath_handed_out_is_what_the_patches_were_gridded_from():
    scenario = replace(load_scenario(builtin_scenario_path("demo")), duration_s=60)
    _, records, swath = simulate_with_swath(scenario)
    assert swath.depth_m.shape == (60, scenario.sensors["sonar"].beams) and swath.reckoned_m.shape == (60, 2)
    assert np.all(swath.reckoned_m[0] == 0.0) and np.isnan(swath.depth_m).mean() == pytest.approx(0.1, abs=0.02)
    # The last record's patch holds every sounding of its pings: the same depths as the swath's, in the same order.
    east, north, depth, age = records.sonar[-1].soundings.arrays()
    pings = np.unique(59 - np.round(age).astype(int))
    np.testing.assert_array_equal(depth, swath.depth_m[pings][np.isfinite(swath.depth_m[pings])])
