"""Where the terrain looks alike: the runner-up of a correlation centred at each node, beside the Cramer-Rao bound.

The bound (:mod:`lost.host.plan.accuracy`) describes the errors about the true position once a filter holds it. A
filter can also lock onto another placement that fits nearly as well: then its error is the distance to that
placement, tens or hundreds of metres, whatever the bound says. For a patch centred at node ``p`` and a placement
``q = p + delta``, the expected mean-compensated squared misfit of the map at ``q`` against the map at ``p`` is

    D(p, delta) = mean_k (m(p+k) - m(q+k))^2 - (mean_k (m(p+k) - m(q+k)))^2

per patch node (the sonar sees the floor at ``p``; the mean compensation removes any depth offset). With ``n``
patch nodes and the noise variance ``s^2`` (the sonar's plus the map's own over the patch), a Gaussian likelihood
prefers the truth over ``q`` by ``n D / (2 s^2)`` in log-likelihood on average, with a standard deviation of
``sqrt(n D) / s``: the separation ``snr = n D / s^2`` says how often one patch prefers ``q`` (``Phi(-sqrt(snr) / 2)``).
The planner keeps, for each distance ring around ``p`` (:data:`RING_NODES`), the smallest ``snr`` of a placement in
the ring and that placement's distance; :mod:`lost.host.plan.route` turns them into a probability of a false lock
and the error it brings.

The sums over the patch are a cross-correlation of the patch with its search window (FFT, a batch of centres at a
time) and box sums from an integral image. Centres lie on a lattice thin enough to bound the work (``work``: the
centres times the nodes of each one's FFT): every second node of a 200 x 300 map searched 600 m at 25 m, every 30th
of a 2000 x 2000 map at 10 m. Every node takes its nearest centre's values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import fft, ndimage
from scipy.special import ndtr

from ..grid import Grid
from .accuracy import SonarModel

__all__ = ["RING_NODES", "Lookalike", "lookalike_grid"]

#: Outer edges of the distance rings, in map nodes (Euclidean), beyond the two nodes next to the truth (which the
#: bound describes); the last ring ends at the search radius.
RING_NODES = (4.0, 8.0, 16.0, 32.0)

#: How much less the filters make of a patch's contrast against a look-alike than independent Gaussian residuals would:
#: the map's errors are correlated over a patch and the filters learn their misfit level from the data. Fitted to the
#: point-mass filter's Monte Carlo on the four shipped floors (``benchmarks/plan_fit.py``; held out of the fit, a floor's
#: share of segments within 1.5x falls: ``docs/campaign.md``).
EVIDENCE_SCALE = 32.0

#: The placements within this many nodes (Chebyshev) of the truth are the truth's own peak, not a look-alike.
EXCLUSION_NODES = 2


@dataclass(frozen=True)
class Lookalike:
    """The runner-up of every node's patch, per distance ring.

    Attributes
    ----------
    ring_edges_m : np.ndarray
        Outer edge of each ring, metres (the inner edge is the previous ring's outer edge, or the exclusion).
    snr : np.ndarray
        ``(rings, rows, cols)``: the smallest ``n D / s^2`` of a placement in the ring (NaN: no bound, no placement).
    distance_m : np.ndarray
        ``(rings, rows, cols)``: that placement's distance from the truth, metres.
    rivals : np.ndarray
        ``(rings, rows, cols)``: the look-alikes of the ring, counted by their chance to win one patch: the sum of
        ``Phi(-sqrt(snr / evidence_scale) / 2)`` over the basins of the misfit in the ring (a basin's lowest placement
        stands for it: neighbouring placements are one look-alike, not many; a tile repeated eight times in the ring is
        eight), and at least the best placement's chance. Their sum over the rings bounds the chance that a patch locks on one of them.
    evidence_scale : float
        How much less the filters make of a patch's contrast than independent Gaussian residuals would
        (:data:`EVIDENCE_SCALE`).
    """

    ring_edges_m: np.ndarray
    snr: np.ndarray
    distance_m: np.ndarray
    rivals: np.ndarray
    evidence_scale: float

    def best(self) -> tuple[np.ndarray, np.ndarray]:
        """The smallest ``snr`` over every ring, and its placement's distance (metres): the grid's runner-up."""
        filled = np.where(np.isnan(self.snr), np.inf, self.snr)
        ring = np.argmin(filled, axis=0)
        snr = np.take_along_axis(self.snr, ring[None], axis=0)[0]
        distance = np.take_along_axis(self.distance_m, ring[None], axis=0)[0]
        return snr, distance


def _integral_sums(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The sum over the ``shape`` window whose top-left node is each node (as far as the window fits)."""
    h, w = shape
    table = np.zeros((values.shape[0] + 1, values.shape[1] + 1))
    table[1:, 1:] = values.cumsum(axis=0).cumsum(axis=1)
    return table[h:, w:] - table[:-h, w:] - table[h:, :-w] + table[:-h, :-w]


def lookalike_grid(grid: Grid, sonar: SonarModel, map_sigma_m: np.ndarray | float = 0.0, *, radius_m: float = 600.0,
                   work: float = 1e8, batch: int = 128, evidence_scale: float = EVIDENCE_SCALE) -> Lookalike:
    """The runner-up's separation and distance per ring at every node (module docstring).

    ``radius_m`` is the search radius (the look-alike check's, ``NavParameters.lookalike_radius_m``); ``map_sigma_m``
    the map's 1-sigma error per node (an array of the grid's shape) or one number. ``work`` bounds the centres times the
    nodes of each one's search window (its FFT): the lattice of centres thins until it fits.
    """
    if not (np.isfinite(radius_m) and radius_m > 0):
        raise ValueError(f"the look-alike search radius must be a positive number of metres, got {radius_m!r}")
    depth = grid.depth_m
    rows, cols = depth.shape
    h, w = sonar.shape
    reach = max(int(radius_m // grid.node_m), EXCLUSION_NODES + 1)
    edges = np.array([e for e in RING_NODES if e < reach] + [float(reach)])
    holes = ~np.isfinite(depth)
    level = float(np.nanmean(depth)) if (~holes).any() else 0.0
    pad = ((reach, reach + h), (reach, reach + w))
    filled = np.pad(np.where(holes, 0.0, depth - level), pad)  # depths about their mean: the FFT's sums stay exact enough
    outside = np.pad(holes, pad, constant_values=True)
    sum1 = _integral_sums(filled, (h, w))  # indexed by the padded top-left node of a placement
    sum2 = _integral_sums(filled * filled, (h, w))
    spoiled = _integral_sums(outside.astype(np.float64), (h, w)) > 0.5
    sigma = np.broadcast_to(np.asarray(map_sigma_m, dtype=np.float64), depth.shape)
    noise = sonar.noise_m**2 + _integral_sums(np.pad(np.where(holes, 0.0, sigma**2), pad), (h, w)) / (h * w)

    window_nodes = float(np.prod([fft.next_fast_len(2 * reach + size, real=True) for size in (h, w)]))
    stride = max(1, int(np.ceil(np.sqrt(rows * cols * window_nodes / work))))
    centre_rows = np.arange(h // 2, rows - (h - 1 - h // 2), stride)
    centre_cols = np.arange(w // 2, cols - (w - 1 - w // 2), stride)
    rings = len(edges)
    snr = np.full((rings, len(centre_rows), len(centre_cols)), np.nan)
    dist, rivals = np.full_like(snr, np.nan), np.full_like(snr, np.nan)
    if centre_rows.size and centre_cols.size:
        _fill(filled, sum1, sum2, spoiled, noise, centre_rows, centre_cols, (h, w), reach, edges, grid.node_m, evidence_scale,
              (snr, dist, rivals), batch)
    index_r = np.clip(np.rint((np.arange(rows) - h // 2) / stride).astype(int), 0, max(len(centre_rows) - 1, 0))
    index_c = np.clip(np.rint((np.arange(cols) - w // 2) / stride).astype(int), 0, max(len(centre_cols) - 1, 0))
    full = [np.full((rings, rows, cols), np.nan) for _ in range(3)]
    if centre_rows.size and centre_cols.size:
        for whole, lattice in zip(full, (snr, dist, rivals)):
            whole[:] = lattice[:, index_r][:, :, index_c]
    inside = np.zeros((rows, cols), dtype=bool)
    inside[h // 2: rows - (h - 1 - h // 2), w // 2: cols - (w - 1 - w // 2)] = True
    top_left_spoiled = spoiled[reach: reach + rows, reach: reach + cols]
    undefined = ~inside | np.roll(np.roll(top_left_spoiled, h // 2, axis=0), w // 2, axis=1)
    for whole in full:
        whole[:, undefined] = np.nan
    return Lookalike(ring_edges_m=edges * grid.node_m, snr=full[0], distance_m=full[1], rivals=full[2], evidence_scale=evidence_scale)


def _fill(filled, sum1, sum2, spoiled, noise, centre_rows, centre_cols, shape, reach, edges, node_m, scale, out, batch) -> None:
    """The rings' smallest separation, its distance and the rivals for every lattice centre, a batch of centres at a time."""
    snr, dist, rivals = out
    h, w = shape
    n = h * w
    side = 2 * reach + 1
    window_shape = (side + h - 1, side + w - 1)
    windows = sliding_window_view(filled, window_shape)
    fast = tuple(fft.next_fast_len(size, real=True) for size in window_shape)  # zero padding beyond the window wraps nothing into the kept lags
    placements = {name: sliding_window_view(values, (side, side)) for name, values in (("s1", sum1), ("s2", sum2), ("bad", spoiled))}
    di, dj = np.mgrid[-reach: reach + 1, -reach: reach + 1]
    radius = np.hypot(di, dj).ravel()
    ring_of = np.searchsorted(edges, radius, side="left")  # ring k: edges[k-1] < r <= edges[k]
    ring_of[(np.maximum(np.abs(di), np.abs(dj)).ravel() <= EXCLUSION_NODES) | (radius > edges[-1])] = len(edges)
    order = np.argsort(ring_of, kind="stable")  # the placements ring by ring, so each ring is one slice
    bounds = np.searchsorted(ring_of[order], np.arange(len(edges) + 1))
    ring_radius = radius[order] * node_m
    rr, cc = np.meshgrid(centre_rows, centre_cols, indexing="ij")
    rr, cc = rr.ravel(), cc.ravel()
    for lo in range(0, rr.size, batch):
        r, c = rr[lo: lo + batch] - h // 2, cc[lo: lo + batch] - w // 2  # top-left of the patch = the window's (padded coordinates)
        win = windows[r, c]
        patch = win[:, reach: reach + h, reach: reach + w]
        spectrum = fft.rfft2(win, s=fast) * np.conj(fft.rfft2(patch, s=fast))
        cross = fft.irfft2(spectrum, s=fast)[:, :side, :side]
        s1, s2 = placements["s1"][r, c], placements["s2"][r, c]
        s1p, s2p = s1[:, reach, reach, None, None], s2[:, reach, reach, None, None]
        misfit = np.maximum((s2p - 2.0 * cross + s2) / n - ((s1p - s1) / n) ** 2, 0.0)
        separation = n * misfit / noise[r + reach, c + reach][:, None, None]
        separation[placements["bad"][r, c]] = np.inf
        flat = separation.reshape(len(r), -1)[:, order]
        # one look-alike is one basin of the misfit: its lowest placement stands for it (its neighbours are the same match)
        lowest = np.isfinite(separation) & (separation <= ndimage.minimum_filter(separation, size=(1, 3, 3), mode="nearest"))
        basins = lowest.reshape(len(r), -1)[:, order]
        ci, cj = np.unravel_index(np.arange(lo, lo + len(r)), (snr.shape[1], snr.shape[2]))
        for k in range(len(edges)):
            if bounds[k] == bounds[k + 1]:
                continue
            part = flat[:, bounds[k]: bounds[k + 1]]
            best = np.argmin(part, axis=1)
            value = part[np.arange(len(r)), best]
            snr[k, ci, cj] = np.where(np.isfinite(value), value, np.nan)
            dist[k, ci, cj] = np.where(np.isfinite(value), ring_radius[bounds[k] + best], np.nan)
            chances = np.where(basins[:, bounds[k]: bounds[k + 1]], ndtr(-np.sqrt(part / scale) / 2.0), 0.0)
            count = np.maximum(chances.sum(axis=1), chances[np.arange(len(r)), best])  # the best placement is one rival at least
            rivals[k, ci, cj] = np.where(np.isfinite(value), count, np.nan)
