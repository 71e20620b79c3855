"""The sonar's patches: gridded on the map's nodes, or binned from a multibeam swath by dead reckoning."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..grid import Grid
from ..records import SonarPatch
from .floor import cell_mean_depth, floor_depth
from .spec import SonarSpec

__all__ = ["sonar_patches", "SwathSoundings"]


@dataclass(frozen=True)
class SwathSoundings:
    """What a ``"swath"`` sonar sounded, ping by ping (one ping per record of the tow), and the dead reckoning that placed it.

    Attributes
    ----------
    depth_m : (pings, beams)
        Each beam's sounding of the true floor with the sonar's bias, noise and outliers; NaN for a beam without a return.
    across_m : (beams,)
        Each beam's offset to starboard of the vehicle's motion, metres (a vehicle at rest looks north).
    reckoned_m : (pings, 2)
        The position, east and north, the patches placed each ping at: the measured velocity integrated from zero
        at the first ping, a dropped reading holding the last one. Only its differences mean anything.
    """

    depth_m: np.ndarray
    across_m: np.ndarray
    reckoned_m: np.ndarray


def sonar_patches(
    rng: np.random.Generator, floor: Grid, node_m: float, truth: np.ndarray, measured_velocity: np.ndarray, spec: SonarSpec, rate_hz: float,
    sounded: list[SwathSoundings] | None = None,
) -> tuple:
    """Patches on the map's nodes (``node_m``) of soundings of the true ``floor``.

    A ``"swath"`` sonar appends its :class:`SwathSoundings` to ``sounded`` when given one (the draws are the same either way).
    """
    if not spec.enabled:
        return ()
    every = max(int(round(spec.interval_s * rate_hz)), 1)
    at = np.arange(0, truth.shape[0], every)
    patches: list[SonarPatch | None] = [None] * truth.shape[0]
    if spec.mode == "swath":
        for n, patch in zip(at, _swath_patches(rng, floor, node_m, truth, measured_velocity, spec, rate_hz, at, sounded)):
            patches[n] = patch
        return tuple(patches)
    h, w = spec.shape
    north = (np.arange(h) - (h - 1) / 2) * node_m
    east = (np.arange(w) - (w - 1) / 2) * node_m
    x = truth[at, 0][:, None, None] + east[None, None, :]
    y = truth[at, 1][:, None, None] + north[None, :, None]
    x, y = np.broadcast_arrays(x, y)
    depth = _sound(rng, cell_mean_depth(floor, x, y, node_m), spec)
    for k, n in enumerate(at):
        patches[n] = SonarPatch(depth_m=depth[k], node_m=node_m)
    return tuple(patches)


def _sound(rng: np.random.Generator, true_depth: np.ndarray, spec: SonarSpec) -> np.ndarray:
    """Soundings of true depths: bias, noise, outliers, and NaN for the beams with no return."""
    depth = true_depth + spec.bias + rng.normal(0.0, spec.noise, true_depth.shape)
    outliers = rng.random(depth.shape) < spec.outlier_rate
    depth[outliers] += rng.uniform(-spec.outlier, spec.outlier, int(outliers.sum()))
    depth[rng.random(depth.shape) < spec.missing_beam_rate] = np.nan
    return depth


def _swath_patches(
    rng: np.random.Generator, floor: Grid, node_m: float, truth: np.ndarray, measured_velocity: np.ndarray, spec: SonarSpec, rate_hz: float,
    at: np.ndarray, sounded: list[SwathSoundings] | None,
) -> list[SonarPatch | None]:
    from ..io.sonar import grid_soundings, patch_pings

    h, w = spec.shape
    dt = 1.0 / rate_hz
    velocity = np.gradient(truth, dt, axis=0)
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    # Beams across the vehicle's motion (to starboard positive); a vehicle at rest looks north.
    motion = np.where(speed[:, None] > 1e-6, velocity / np.maximum(speed, 1e-6)[:, None], (0.0, 1.0))
    starboard = np.column_stack([motion[:, 1], -motion[:, 0]])
    width = spec.swath_width_m if spec.swath_width_m is not None else max(h, w) * node_m
    across = np.linspace(-width / 2, width / 2, spec.beams)
    beam_offsets = across[None, :, None] * starboard[:, None, :]  # (pings, beams, 2)
    spots = truth[:, None, :] + beam_offsets
    depth = _sound(rng, floor_depth(floor, spots[..., 0], spots[..., 1]), spec)
    # Where the navigation believes each ping was: dead reckoning on the measured velocity, a dropped
    # reading holding the last one.
    held = measured_velocity.copy()
    for n in range(1, held.shape[0]):
        if np.isnan(held[n]).any():
            held[n] = held[n - 1]
    held[np.isnan(held)] = 0.0
    reckoned = np.vstack([np.zeros(2), np.cumsum(held[:-1] * dt, axis=0)])
    if sounded is not None:
        sounded.append(SwathSoundings(depth_m=depth, across_m=across, reckoned_m=reckoned))
    # The pings whose reckoned position lies within half a patch diagonal of the vehicle's, looked
    # for at most max_window_s away: a slow vehicle gathers pings for longer.
    half_diagonal = math.hypot(h, w) * node_m / 2
    window = int(np.ceil(spec.max_window_s * rate_hz))
    soundings = _SoundedBeams(depth, beam_offsets)
    patches: list[SonarPatch | None] = []
    for n in at:
        centre, pings = patch_pings(reckoned, int(n), window, half_diagonal, spec.realtime)
        placed = _PatchPings(soundings, reckoned, pings, int(n), dt)
        east, north, sounded_depth, age = placed.arrays()
        patches.append(grid_soundings(
            east, north, sounded_depth, patch_shape=(h, w), node_m=node_m, centre_m=tuple(reckoned[centre] - reckoned[n]), age_s=age,
            soundings=placed,
        ).patch)
    return patches


class _PatchPings:
    """One patch's soundings (:class:`~lost.host.records.PatchSoundings`), made when asked from the tow's shared arrays:
    a patch keeps a few numbers, not its thousands of soundings, for every record of a long tow."""

    def __init__(self, soundings: _SoundedBeams, reckoned: np.ndarray, pings: np.ndarray, record: int, dt_s: float) -> None:
        self._soundings, self._reckoned, self._pings, self._record, self._dt = soundings, reckoned, pings, record, dt_s

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        east, north, depth, ping = self._soundings.of(self._pings)
        here = self._reckoned[self._record]
        return (east + (self._reckoned[ping, 0] - here[0]), north + (self._reckoned[ping, 1] - here[1]), depth,
                (self._record - ping) * self._dt)


class _SoundedBeams:
    """The soundings with a return, ping after ping (beams in order within a ping), so that the soundings of a run of
    consecutive pings are one slice: a patch takes them without a mask over every beam of its pings."""

    def __init__(self, depth: np.ndarray, beam_offsets: np.ndarray) -> None:
        sounded = np.isfinite(depth)
        self.depth = depth[sounded]
        self.east = beam_offsets[..., 0][sounded]
        self.north = beam_offsets[..., 1][sounded]
        self.ping = np.nonzero(sounded)[0]
        self.first = np.concatenate([[0], np.cumsum(sounded.sum(axis=1))])  # ping p's soundings: first[p] to first[p + 1]

    def of(self, pings: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(east offset of the beam, north offset, depth, ping) of every sounding of ``pings`` (ascending)."""
        if pings.size and pings[-1] - pings[0] + 1 == pings.size:
            chosen = slice(self.first[pings[0]], self.first[pings[-1] + 1])
        else:
            chosen = np.concatenate([np.arange(self.first[p], self.first[p + 1]) for p in pings]) if pings.size else np.zeros(0, np.int64)
        return self.east[chosen], self.north[chosen], self.depth[chosen], self.ping[chosen]
