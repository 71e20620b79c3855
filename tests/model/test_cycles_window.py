"""The window correlator's cycle model: its constants, its step plan and its closed forms.

The simulations (tests/hdl/test_window.py) check every beat's cycle against :func:`schedule`; these
tests check the model against properties derived independently of its code.
"""

import itertools

import numpy as np
import pytest

from lost.model.cycles import reducer_latency, surface_beats
from lost.model.cycles_window import QUOTIENT_STAGES, completing_steps, schedule, window_timing


def brute_force_completing_steps(map_shape, patch_shape, lanes):
    """The first step after which every column of a beat's windows has been read, found by walking steps.

    Steps read memory rows in raster order, map row ``r`` in ``ceil(W / L)`` rows of ``L`` columns;
    a beat may only be completed by a step of its own last map row (``i + h - 1``) or, if that row has
    no step left, the step right after it. A beat's windows end in column ``j + count - 1 + w - 1``.
    """
    (H, W), (h, w) = map_shape, patch_shape
    groups = -(-W // lanes)
    steps = []
    for i, j, count in surface_beats((H - h + 1, W - w + 1), lanes):
        last_column = j + count - 1 + w - 1
        row = i + h - 1
        group = last_column // lanes
        # The step that reads this column; a beat whose lanes end early is still emitted in lockstep
        # with its first lane's window, which ends in column j + L - 1 + w - 1.
        lockstep_group = (j + lanes - 1 + w - 1) // lanes
        step = row * groups + lockstep_group if lockstep_group < groups else (row + 1) * groups
        assert step >= row * groups + group  # never before the data is there
        steps.append(step)
    return np.array(steps)


SHAPES = [((H, W), (h, w), L)
          for H, W, h, w, L in itertools.product([3, 7], [1, 4, 9, 13], [1, 3], [1, 2, 4, 5], [1, 2, 3, 4, 8])
          if h <= H and w <= W]


@pytest.mark.parametrize("map_shape, patch_shape, lanes", SHAPES)
def test_completing_steps_match_a_walk(map_shape, patch_shape, lanes):
    np.testing.assert_array_equal(completing_steps(map_shape, patch_shape, lanes),
                                  brute_force_completing_steps(map_shape, patch_shape, lanes))


@pytest.mark.parametrize("map_shape, patch_shape, lanes", SHAPES)
def test_schedule_shape_and_steady_rate(map_shape, patch_shape, lanes):
    (H, W), (h, w) = map_shape, patch_shape
    timing = window_timing(map_shape, patch_shape, lanes)
    plan = schedule(map_shape, patch_shape, lanes)
    beats = surface_beats((H - h + 1, W - w + 1), lanes)
    assert plan.surface.shape == (len(beats),)
    # Strictly increasing; within a row's beats (except a wrapped last one) one per clock.
    assert np.all(np.diff(plan.surface) >= 1)
    per_row = plan.surface.reshape(H - h + 1, timing.out_groups)
    assert np.all(np.diff(per_row[:, :-1], axis=1) == 1)
    # Consecutive surface rows are one map row (G steps) apart.
    assert np.all(np.diff(per_row, axis=0) == timing.groups)
    # The map is read once: the last beat is completed by the last map step, or by one flush step.
    last_step = H * timing.groups - 1 + int(timing.wraps)
    assert plan.surface[-1] == h * w + 5 + last_step + timing.output_delay + 1
    assert plan.best == plan.surface[-1] + reducer_latency((H - h + 1, W - w + 1), lanes, 1)


def test_full_size_nygren_figures():
    """501 x 501 map, 10 x 10 patch: H * ceil(W / L) steps, so one clock per L placements."""
    for lanes, groups in [(1, 501), (4, 126), (8, 63)]:
        timing = window_timing((501, 501), (10, 10), lanes)
        assert timing.groups == groups
        assert timing.sum_levels == 7
        plan = schedule((501, 501), (10, 10), lanes)
        assert plan.surface.size == 492 * -(-492 // lanes)
        assert plan.surface[-1] - plan.surface[0] < 501 * groups


@pytest.mark.parametrize("patch_shape, levels", [((1, 1), 0), ((1, 2), 1), ((3, 3), 4), ((10, 10), 7), ((16, 16), 8)])
def test_stage_counts(patch_shape, levels):
    """Step stages: step register, window register, window-sum levels; term stages: f*M - C, minus the
    window sum, max(z, 0), value-tree levels, 2 * sum - correction. The queue covers a credit's
    round trip, issue to transfer, so that steps issue one per clock."""
    timing = window_timing((20, 20), patch_shape, 2)
    assert timing.sum_levels == levels
    assert (timing.step_stages, timing.term_stages) == (levels + 4 + QUOTIENT_STAGES, levels + 5)
    assert timing.output_delay == 2 * levels + 9 + QUOTIENT_STAGES
    assert timing.queue_depth == timing.output_delay + 3
    # Enough flush steps to carry the last completing step through the step-synchronous stages.
    assert timing.flush_steps == int(timing.wraps) + timing.step_stages - 1


def test_wrap_case_is_one_step_late():
    """W=4, w=2, L=2: beats of columns (0, 1) and (2,); the second needs columns 2-3, read with group 1,
    but lockstep lanes put it one step later, at the next row's first step."""
    timing = window_timing((3, 4), (1, 2), 2)
    assert timing.wraps and timing.lead == 1 and timing.groups == 2
    np.testing.assert_array_equal(completing_steps((3, 4), (1, 2), 2), [1, 2, 3, 4, 5, 6])


def test_mask_and_mode_do_not_change_the_schedule():
    mask = np.zeros((3, 2), dtype=bool)
    mask[1, 0] = True
    plain = schedule((8, 9), (3, 2), 2)
    for mode in (True, False):
        masked = schedule((8, 9), (3, 2), 2, mask, mode)
        np.testing.assert_array_equal(masked.surface, plain.surface)
        assert masked.best == plain.best
    with pytest.raises(ValueError, match="no valid node"):
        schedule((8, 9), (3, 2), 2, np.zeros((3, 2), dtype=bool))
    with pytest.raises(ValueError, match="shape"):
        schedule((8, 9), (3, 2), 2, np.ones((2, 3), dtype=bool))


def test_radius_changes_only_the_best_beat():
    near, far = schedule((9, 9), (2, 2), 1, exclusion_radius=0), schedule((9, 9), (2, 2), 1, exclusion_radius=2)
    np.testing.assert_array_equal(near.surface, far.surface)
    assert far.best - near.best == (6 - 2) * 8  # 2r + 2 row slots of 8 one-value words to scan


@pytest.mark.parametrize("args, message", [
    (((4, 4), (5, 4), 1), "larger than the map"),
    (((4, 4), (2, 2), 0), "lanes"),
    (((4, 4), (2, 2), True), "lanes"),
])
def test_bad_arguments_are_refused(args, message):
    with pytest.raises(ValueError, match=message):
        window_timing(*args)
    with pytest.raises(ValueError, match=message):
        schedule(*args)
