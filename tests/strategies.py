"""Hypothesis strategies and the deliberately naive reference shared by the correlator tests."""

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

DEPTH = st.integers(-(2**15), 2**15 - 1)
EXTREMES = st.sampled_from([-(2**15), 2**15 - 1, 0, -1])


@st.composite
def correlation_cases(draw, max_map=14, max_patch=6):
    """(terrain, patch, mask, mean_compensation), with extremes, flat maps and sparse masks."""
    H = draw(st.integers(1, max_map))
    W = draw(st.integers(1, max_map))
    h = draw(st.integers(1, min(H, max_patch)))
    w = draw(st.integers(1, min(W, max_patch)))
    kind = draw(st.sampled_from(["random", "extreme", "flat"]))
    if kind == "flat":
        value = draw(DEPTH)
        terrain = np.full((H, W), value, dtype=np.int16)
    else:
        elements = DEPTH if kind == "random" else EXTREMES
        terrain = draw(hnp.arrays(np.int16, (H, W), elements=elements))
    patch = draw(hnp.arrays(np.int16, (h, w), elements=st.one_of(DEPTH, EXTREMES)))
    mask = draw(st.one_of(st.none(), hnp.arrays(np.bool_, (h, w))))
    if mask is not None and not mask.any():
        mask[draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1))] = True
    return terrain, patch, mask, draw(st.booleans())


def naive_correlate(terrain, patch, mask=None, mean_compensation=True):
    """The definition of ARCHITECTURE.md, one placement and one node at a time, in Python ints."""
    H, W = terrain.shape
    h, w = patch.shape
    if mask is None:
        mask = np.ones((h, w), dtype=bool)
    nodes = [(k, l) for k in range(h) for l in range(w) if mask[k, l]]
    n = len(nodes)
    V = np.zeros((H - h + 1, W - w + 1), dtype=object)
    for i in range(H - h + 1):
        for j in range(W - w + 1):
            m = {(k, l): int(terrain[i + k, j + l]) for k, l in nodes}
            s = {(k, l): int(patch[k, l]) for k, l in nodes}
            if mean_compensation:
                centre = sum(m.values()) - sum(s.values())
                V[i, j] = sum(abs(n * (m[p] - s[p]) - centre) for p in nodes)
            else:
                V[i, j] = sum(abs(m[p] - s[p]) for p in nodes)
    return V
