"""The swath's soundings taken ping by ping: a slice for a run of consecutive pings, and the same soundings otherwise."""

import numpy as np

from lost.host.scenario.swath import _SoundedBeams


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
