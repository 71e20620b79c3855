"""Cycle model of the window correlator (:mod:`lost.hdl.window`).

The window core works in *steps*: each takes one memory row of ``L`` map words (or, after the last
one, a flush step without a word). A step is issued (a map read request, or a flush step) when the
core holds a credit for it, and taken on the next edge; the step-synchronous stages (step register,
line buffers, window register, masked depths, window-sum levels, quotient stages) load only when a
step is taken, while the term stages after them run on every clock. With ``surface.ready`` and ``best.ready`` held high and the
patch and map loaded, counting from the edge on which the ``start`` beat transfers (cycle 0):

* cycles ``1 .. hw + 3`` read the patch once, for ``n``, ``sum_valid S`` and the lifted depths
  ``2**b - S`` (``hw`` nodes plus two register stages after the patch memory, and one for the
  divider's bias); the first map read request transfers on edge ``hw + 4``;
* one step is issued per clock (the output queue's ``queue_depth`` credits never run out with
  ``surface.ready`` high), in raster order of the ``H * ceil(W / L)`` memory rows, then the flush
  steps; step ``t`` (counting map words first, flush steps after) is taken on edge ``hw + 5 + t``;
* the beat ``(i, g)`` (surface row ``i``, its ``g``-th group of ``L`` placements) is completed by step
  ``(i + h - 1) * G + g + D`` with ``G = ceil(W / L)`` and ``D = ceil((w - 1) / L)``, the step whose
  memory row holds the rightmost column of the beat's ``L`` windows (the lanes run in lockstep, also
  past a row's end), unless ``g + D`` runs past the row
  (possible only for a row's last beat), when the next map row's first step (or a flush step, after
  the last row) completes it: step ``(i + h) * G``;
* a step's beat is written into the output queue ``output_delay`` edges after the step is taken (the
  ``step_stages - 1`` steps after it follow one per clock, then ``term_stages`` clocked stages) and
  transfers on the next edge;
* the best beat follows the last surface beat by :func:`lost.model.cycles.reducer_latency`.

So beat ``(i, g)`` transfers on edge ``hw + 5 + step(i, g) + output_delay + 1`` with
``output_delay = 2 * ceil(log2(h * w)) + 9 + QUOTIENT_STAGES``. The schedule does not depend on the data, the mask or
the mode. Numpy only; :mod:`lost.hdl.window` sizes its pipeline from :func:`window_timing`, so the
gateware and this model share every constant.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cycles import Schedule, reducer_latency
from .widths import placement_widths

__all__ = ["QUOTIENT_STAGES", "WindowTiming", "completing_steps", "schedule", "window_timing"]

# The window core divides each placement's dividend by n in this many step-synchronous stages (the
# count of a one-bit-a-stage divider for depths of up to 16 bits, whose quotients have 17; the gateware
# forms the quotient as a reciprocal product in the last stages and the dividend waits in the
# others), so that the schedule does not depend on the depth width nor on how the quotient is made.
QUOTIENT_STAGES = 17


@dataclass(frozen=True)
class WindowTiming:
    """The fixed schedule constants of the window pipeline for one parameter set.

    Attributes
    ----------
    groups : int
        ``G = ceil(W / L)``: memory rows (steps) per map row.
    out_groups : int
        ``ceil((W - w + 1) / L)``: surface beats per surface row.
    lead : int
        ``D = ceil((w - 1) / L)``: steps from the memory row holding a beat's first column to the one
        holding its windows' last column.
    wraps : bool
        A surface row's last beat is completed by the next map row's first step (or, after the last
        row, by one extra flush step), because ``out_groups - 1 + lead == groups``.
    sum_levels : int
        ``ceil(log2(h * w))``: register levels of the window-sum tree and of the value tree.
    prepare_cycles : int
        ``h * w + 3``: cycles after the start beat spent on the pass over the patch.
    step_stages : int
        ``sum_levels + 4 + QUOTIENT_STAGES``: the step-synchronous stages, which load only when a step
        is taken: the step register, the window register, the masked depths, the window-sum levels,
        the dividend and the quotient stages.
    term_stages : int
        ``sum_levels + 5``: the stages that run on every clock: the lifted differences, the selected
        ones (with their count), the levels of their sum trees, the partial products, their sums and
        the value.
    output_delay : int
        ``step_stages + term_stages``: cycles from taking a step to writing its beat into the output
        queue once the ``step_stages - 1`` steps after it have followed one per clock.
    flush_steps : int
        Steps without a map word after the last one, enough to move the last beat out of the
        step-synchronous stages.
    queue_depth : int
        ``output_delay + 3``: beats the output queue holds, and the credits for issuing steps. A step
        holds its credit from its issue to its beat's transfer, ``output_delay + 2`` edges later with
        ``surface.ready`` high, so one step per clock is issued without waiting for a credit.
    """

    groups: int
    out_groups: int
    lead: int
    wraps: bool
    sum_levels: int
    prepare_cycles: int
    step_stages: int
    term_stages: int
    output_delay: int
    flush_steps: int
    queue_depth: int


def window_timing(map_shape: tuple[int, int], patch_shape: tuple[int, int], lanes: int) -> WindowTiming:
    """The schedule constants of the window core.

    Raises
    ------
    ValueError
        A patch larger than the map, or fewer than one lane.
    """
    placement_widths(map_shape, patch_shape)  # validates the shapes
    if isinstance(lanes, bool) or not isinstance(lanes, (int, np.integer)) or lanes < 1:
        raise ValueError(f"lanes must be a positive integer, got {lanes!r}")
    (_, W), (h, w), L = map_shape, patch_shape, int(lanes)
    groups = -(-W // L)
    out_groups = -(-(W - w + 1) // L)
    lead = -(-(w - 1) // L)
    # ceil(a/L) + ceil(b/L) <= ceil((a+b)/L) + 1, so a row's last beat is late by at most one step.
    wraps = out_groups - 1 + lead == groups
    sum_levels = (h * w - 1).bit_length()
    step_stages = sum_levels + 4 + QUOTIENT_STAGES
    term_stages = sum_levels + 5
    output_delay = step_stages + term_stages
    return WindowTiming(
        groups=groups,
        out_groups=out_groups,
        lead=lead,
        wraps=wraps,
        sum_levels=sum_levels,
        prepare_cycles=h * w + 3,
        step_stages=step_stages,
        term_stages=term_stages,
        output_delay=output_delay,
        flush_steps=int(wraps) + step_stages - 1,
        queue_depth=output_delay + 3,
    )


def completing_steps(map_shape: tuple[int, int], patch_shape: tuple[int, int], lanes: int) -> np.ndarray:
    """The step that completes each surface beat, beats in raster order."""
    timing = window_timing(map_shape, patch_shape, lanes)
    (H, _), (h, _) = map_shape, patch_shape
    rows = np.arange(H - h + 1, dtype=np.int64)[:, None]
    groups = np.arange(timing.out_groups, dtype=np.int64)[None, :]
    in_row = groups + timing.lead < timing.groups
    steps = np.where(in_row, (rows + h - 1) * timing.groups + groups + timing.lead, (rows + h) * timing.groups)
    return steps.ravel()


def schedule(map_shape, patch_shape, lanes: int = 1, mask=None, mean_compensation: bool = True, *,
             exclusion_radius: int = 1) -> Schedule:
    """The cycle of every surface beat and of the best beat of one correlation.

    Parameters
    ----------
    map_shape, patch_shape : (int, int)
        ``(H, W)`` and ``(h, w)``.
    lanes : int
        ``L``, placements per beat.
    mask : (h, w) bool array, optional
        The valid patch nodes. The window core's timing does not depend on it (nor on the mode);
        both are taken, and checked, so that both variants' schedules are called alike.
    mean_compensation : bool
        The mode of the start command.
    exclusion_radius : int
        The reducer's radius (its row store, and so its final scan, depends on it).

    Raises
    ------
    ValueError
        A patch larger than the map, fewer than one lane, a mask of another shape or with no valid
        node, a negative radius.
    """
    timing = window_timing(map_shape, patch_shape, lanes)
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != tuple(patch_shape) or mask.dtype != np.bool_:
            raise ValueError(f"mask must be a boolean array of shape {tuple(patch_shape)}, got {mask.dtype} {mask.shape}")
        if not mask.any():
            raise ValueError("mask has no valid node: there is nothing to correlate")
    steps = completing_steps(map_shape, patch_shape, lanes)
    surface = timing.prepare_cycles + 2 + steps + timing.output_delay + 1
    (H, W), (h, w) = map_shape, patch_shape
    best = int(surface[-1]) + reducer_latency((H - h + 1, W - w + 1), lanes, exclusion_radius)
    return Schedule(surface=surface, best=best)
