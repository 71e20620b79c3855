"""The correlator bench's own logic, without a simulator: expected beats and the in-order checker."""

import json

import numpy as np
import pytest

from lost.sim.cocotb.correlator import BenchConfig, InOrderChecker, expected_beats
from lost.sim.cocotb.streams import Transfer


def _beat(i, j, values, count, last, lanes=4):
    return Transfer({"values": list(values) + [0] * (lanes - len(values)), "count": count, "i": i, "j": j,
                     "last": last}, 0)


def test_rows_end_on_a_partial_beat_and_only_the_last_beat_is_last():
    surface = np.arange(2 * 7).reshape(2, 7)
    beats = expected_beats(surface, 4)
    assert [(b.i, b.j, b.values, b.last) for b in beats] == [
        (0, 0, (0, 1, 2, 3), False), (0, 4, (4, 5, 6), False),
        (1, 0, (7, 8, 9, 10), False), (1, 4, (11, 12, 13), True),
    ]


def test_checker_passes_the_right_beats_and_ignores_lanes_beyond_count():
    surface = np.arange(2 * 7).reshape(2, 7)
    checker = InOrderChecker(expected_beats(surface, 4))
    for i in range(2):
        checker(_beat(i, 0, surface[i, :4], 4, 0))
        checker(_beat(i, 4, list(surface[i, 4:]) + [999], 3, int(i == 1)))
    checker.verdict()


@pytest.mark.parametrize("fault", ["value", "position", "last", "missing", "extra"])
def test_checker_reports_each_kind_of_fault(fault):
    surface = np.arange(6).reshape(2, 3)
    checker = InOrderChecker(expected_beats(surface, 1))
    beats = [_beat(i, j, [surface[i, j]], 1, int((i, j) == (1, 2)), lanes=1) for i in range(2) for j in range(3)]
    if fault == "value":
        beats[4].payload["values"][0] += 1
    elif fault == "position":
        beats[2].payload["j"] = 1
    elif fault == "last":
        beats[0].payload["last"] = 1
    elif fault == "missing":
        beats.pop(3)
    else:
        beats.append(beats[-1])
    for beat in beats:
        checker(beat)
    with pytest.raises(AssertionError):
        checker.verdict()


def test_config_refuses_bad_parameters_in_full_sentences():
    with pytest.raises(ValueError, match="variant must be one of"):
        BenchConfig(variant="systolic", map_shape=(8, 8), patch_shape=(2, 2))
    with pytest.raises(ValueError, match="recursive core has one lane"):
        BenchConfig(variant="recursive", map_shape=(8, 8), patch_shape=(2, 2), lanes=4)
    with pytest.raises(ValueError, match="larger than the map"):
        BenchConfig(variant="window", map_shape=(8, 8), patch_shape=(9, 2))
    config = BenchConfig(variant="window", map_shape=(8, 9), patch_shape=(2, 3), lanes=4, seed=7)
    assert BenchConfig(**json.loads(config.to_json())) == config
