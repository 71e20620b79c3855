"""Cycle models of the correlator cores: the types they share and the best-fit reducer's timing.

Each hardware variant has its own module (:mod:`lost.model.cycles_recursive`,
:mod:`lost.model.cycles_window`) whose ``schedule`` predicts, for a run with ``surface.ready`` and
``best.ready`` held high and the patch and map already loaded, the clock edge on which every surface
beat transfers and the one on which the best beat transfers. Cycle 0 is the edge on which the
``start`` beat transfers; cycle ``c`` is the ``c``-th rising edge after it. The simulations check
every beat's cycle against these numbers.

Numpy only, like the rest of :mod:`lost.model`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Schedule", "reducer_geometry", "reducer_latency", "surface_beats"]


@dataclass(frozen=True)
class Schedule:
    """When each beat of one correlation transfers.

    Attributes
    ----------
    surface : (beats,) int64 array
        The cycle of every surface beat, in the order the beats are sent (raster order).
    best : int
        The cycle of the best-fit beat.
    """

    surface: np.ndarray
    best: int

    @property
    def total(self) -> int:
        """Cycles from the start beat to the best beat, both transfers included as edges."""
        return self.best


def _check_surface_shape(surface_shape) -> tuple[int, int]:
    if (len(surface_shape) != 2
            or not all(isinstance(side, (int, np.integer)) and side >= 1 for side in surface_shape)):
        raise ValueError(f"surface_shape must be a pair of positive integers, got {surface_shape!r}")
    return int(surface_shape[0]), int(surface_shape[1])


def _check_lanes_radius(lanes, exclusion_radius) -> None:
    if not isinstance(lanes, (int, np.integer)) or lanes < 1:
        raise ValueError(f"lanes must be a positive integer, got {lanes!r}")
    if not isinstance(exclusion_radius, (int, np.integer)) or exclusion_radius < 0:
        raise ValueError(f"exclusion_radius must be a non-negative integer, got {exclusion_radius!r}")


def surface_beats(surface_shape: tuple[int, int], lanes: int) -> list[tuple[int, int, int]]:
    """The ``(i, j, count)`` of every surface beat in order: each row in ``ceil(Wo / lanes)`` beats."""
    rows, cols = _check_surface_shape(surface_shape)
    _check_lanes_radius(lanes, 0)
    return [(i, j, min(lanes, cols - j)) for i in range(rows) for j in range(0, cols, lanes)]


def reducer_geometry(surface_shape: tuple[int, int], lanes: int, exclusion_radius: int) -> tuple[int, int]:
    """``(slots, beats_per_row)`` of the best-fit reducer's row store.

    ``2r + 2`` row slots hold the rows around the best fit (fewer when the surface has fewer rows),
    each of ``ceil(Wo / lanes)`` memory words.
    """
    rows, cols = _check_surface_shape(surface_shape)
    _check_lanes_radius(lanes, exclusion_radius)
    return min(2 * int(exclusion_radius) + 2, rows), -(-cols // int(lanes))


def reducer_latency(surface_shape: tuple[int, int], lanes: int, exclusion_radius: int) -> int:
    """Cycles from the edge on which the last surface beat transfers to the one on which the best beat does.

    The reducer's collecting pipeline takes ``4 + K`` edges to store the last beat, ``K = ceil(log2
    lanes)`` being the levels of its lane-minimum tree: the beat's register, the tree, the row minimum,
    the best fit, the slot choice; the row-store write is the last of them. The scan then starts: it
    reads each of the ``Ho`` row minima and each of the ``slots * beats_per_row`` row-store words once,
    one per cycle; a word is registered on the edge after it is read and its lane candidates on the
    next, which a ``K``-level tree reduces to one compared with the runner-up on the next edge, after
    which the best beat is offered and transfers on the edge after (with ``best.ready`` high).
    """
    rows, _ = _check_surface_shape(surface_shape)
    slots, beats_per_row = reducer_geometry(surface_shape, lanes, exclusion_radius)
    levels = (int(lanes) - 1).bit_length()  # ceil(log2 lanes)
    return rows + slots * beats_per_row + 2 * levels + 8
