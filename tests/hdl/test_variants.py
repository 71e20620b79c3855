"""Each variant's gateware: the class its kind and memory choose, built with its lane count."""

import pytest
from amaranth.hdl import Fragment

from lost.hdl.recursive import RecursiveCore, RecursiveCorrelator
from lost.hdl.variants import build_core, core_class
from lost.hdl.window import WindowCore, WindowCorrelator
from lost.model.variants import window_variant


@pytest.mark.parametrize(("name", "memory", "expected"), [
    ("recursive_correlator", "on-chip", RecursiveCorrelator),
    ("recursive_correlator", "external", RecursiveCore),
    ("window_correlator_l1", "on-chip", WindowCorrelator),
    ("window_correlator_l4", "external", WindowCore),
])
def test_core_class(name, memory, expected):
    assert core_class(name, memory=memory) is expected


def test_a_window_core_is_built_with_the_variants_lanes():
    core = build_core(window_variant(3), map_shape=(12, 14), patch_shape=(3, 4), memory="external")
    assert isinstance(core, WindowCore)
    assert core.parameters.lanes == 3
    Fragment.get(core, None)  # it elaborates (and is not left unused)


def test_bad_choices_are_refused():
    with pytest.raises(ValueError, match="memory must be 'on-chip' or 'external'"):
        core_class("recursive_correlator", memory="sdram")
    with pytest.raises(ValueError, match="unknown correlator variant"):
        build_core("cordic", map_shape=(8, 8), patch_shape=(2, 2))
