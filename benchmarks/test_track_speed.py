"""Tracker speed: one ping of the multi-target tracker with the paper's 10,000 particles (goal: 20 ms; a ping every 1.3 s).

Run with `make bench` (or `make bench-track` for every goal of the tracking issue, speed included).
The benchmarked call steps the tracker through the next ping of the two-divers scenario, so births,
track updates, EM and the cloud are all in the figure.
"""

import numpy as np

from lost.host.track.simulate import builtin_scenario_path, load_scenario, simulate
from lost.host.track.tracker import MultiTargetTracker, TrackerParameters


def test_tracker_ping_with_10000_particles(benchmark):
    sim = simulate(load_scenario(builtin_scenario_path("two_divers")))
    tracker = MultiTargetTracker(sonar=sim.scenario.sonar.sonar, parameters=TrackerParameters(particles=10_000), rng=np.random.default_rng(0))
    for ping in sim.pings[:20]:
        tracker.step(ping)  # past the first pings, when the cloud is still spread over the sector
    pings = iter(sim.pings[20:])  # 288 more, in order
    benchmark.pedantic(lambda: tracker.step(next(pings)), rounds=250, iterations=1, warmup_rounds=5)
    assert tracker.tracks
