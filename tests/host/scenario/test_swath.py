"""The swath's soundings: taken ping by ping (a slice for a run of consecutive pings), handed out without changing a record."""

import hashlib
from dataclasses import fields, replace

import numpy as np
import pytest

from lost.host.scenario import builtin_scenario_path, builtin_scenarios, load_scenario, simulate
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


#: A fingerprint of each shipped scenario's records over its first 120 s (every series, every patch's depths, centre, age
#: and soundings): handing out a swath's soundings must leave them bit for bit as they were. Change one only on purpose.
SHIPPED_RECORDS = {
    "coarse_map": "738e7f2609a20d49",
    "demo": "b57257aaab0898c5",
    "lookalike": "755607af6cdf9d74",
    "map_short": "c072056d8560a448",
    "offset": "f307c2e8d1b836d6",
    "seamount_ridges": "d3b51b78debb07e2",
    "shelf_canyon": "d3b69f4d41f8a20f",
    "short": "8a2322ef95a5071d",
    "short_exact_map": "cc64d3c972effa84",
    "two_hour": "c75956b620d98a85",
    "usbl_nav": "d9a6a57db2778a48",
}


def _fingerprint(records) -> str:
    digest = hashlib.sha256()
    for f in fields(records):
        value = getattr(records, f.name)
        if f.name != "sonar":
            if value is not None:
                digest.update(np.ascontiguousarray(value, dtype=np.float64).tobytes())
            continue
        for patch in value:
            if patch is None:
                digest.update(b"none")
                continue
            digest.update(np.ascontiguousarray(patch.depth_m, dtype=np.float64).tobytes())
            digest.update(np.array([patch.node_m, *patch.centre_offset_m, patch.age_s], dtype=np.float64).tobytes())
            if patch.soundings is not None:
                for column in patch.soundings.arrays():
                    digest.update(np.ascontiguousarray(column, dtype=np.float64).tobytes())
    return digest.hexdigest()[:16]


def test_every_shipped_scenarios_records_are_unchanged_by_handing_out_its_swath():
    assert sorted(SHIPPED_RECORDS) == sorted(builtin_scenarios())
    for name, expected in SHIPPED_RECORDS.items():
        scenario = load_scenario(builtin_scenario_path(name))
        scenario = replace(scenario, duration_s=min(scenario.duration_s, 120))
        _, records, swath = simulate_with_swath(scenario)
        assert _fingerprint(records) == expected, name
        assert (swath is None) == (scenario.sensors["sonar"].mode != "swath"), name
    _, records = simulate(scenario)
    assert _fingerprint(records) == expected


def test_the_swath_handed_out_is_what_the_patches_were_gridded_from():
    scenario = replace(load_scenario(builtin_scenario_path("demo")), duration_s=60)
    _, records, swath = simulate_with_swath(scenario)
    assert swath.depth_m.shape == (60, scenario.sensors["sonar"].beams) and swath.reckoned_m.shape == (60, 2)
    assert np.all(swath.reckoned_m[0] == 0.0) and np.isnan(swath.depth_m).mean() == pytest.approx(0.1, abs=0.02)
    # The last record's patch holds every sounding of its pings: the same depths as the swath's, in the same order.
    east, north, depth, age = records.sonar[-1].soundings.arrays()
    pings = np.unique(59 - np.round(age).astype(int))
    np.testing.assert_array_equal(depth, swath.depth_m[pings][np.isfinite(swath.depth_m[pings])])
