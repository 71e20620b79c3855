"""The variant table: names, numbers, kinds, lanes and cycle models, and the lookups that read it."""

import numpy as np
import pytest

from lost.model import cycles_recursive, cycles_window
from lost.model.device import reference_info
from lost.model.protocol import DeviceInfo
from lost.model.variants import (
    DEFAULT_VARIANT,
    KINDS,
    VARIANTS,
    of_kind,
    variant,
    variant_by_id,
    window_variant,
)


def test_the_registered_variants():
    rows = {(v.name, v.ident, v.kind, v.lanes) for v in VARIANTS.values()}
    assert rows == {("recursive_correlator", 0, "recursive", 1), ("window_correlator_l1", 1, "window", 1),
                    ("window_correlator_l4", 4, "window", 4)}
    assert DEFAULT_VARIANT in VARIANTS
    assert {v.kind for v in VARIANTS.values()} == set(KINDS)


@pytest.mark.parametrize("ident", [0, 1, 2, 4, 7, 255])
def test_the_identify_number_names_the_variant_both_ways(ident):
    found = variant_by_id(ident)
    assert found.ident == ident
    assert variant_by_id(found.ident) == found
    assert found == of_kind(found.kind, found.lanes)
    info = reference_info(variant=ident)
    assert (info.variant_name, info.lanes) == (found.name, found.lanes)
    assert DeviceInfo.decode(info.encode()).variant_name == found.name


def test_unregistered_lane_counts_are_window_variants():
    assert window_variant(4) is VARIANTS["window_correlator_l4"]
    three = window_variant(3)
    assert (three.name, three.ident, three.kind, three.lanes) == ("window_correlator_l3", 3, "window", 3)


@pytest.mark.parametrize(("call", "message"), [
    (lambda: variant("cordic"), "unknown correlator variant 'cordic'.*recursive_correlator"),
    (lambda: variant_by_id(256), "variant number 256"),
    (lambda: variant_by_id(-1), "variant number -1"),
    (lambda: window_variant(0), "lanes must be a positive integer"),
    (lambda: window_variant(True), "lanes must be a positive integer"),
    (lambda: of_kind("systolic"), "variant must be one of"),
    (lambda: of_kind("recursive", 2), "recursive core has one lane"),
    (lambda: of_kind("window", 0), "lanes must be a positive integer"),
])
def test_bad_lookups_name_the_problem(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_each_variant_schedules_with_its_own_cycle_model():
    mask = np.random.default_rng(5).random((5, 4)) < 0.7
    recursive = variant("recursive_correlator").schedule((23, 30), (5, 4), mask, True, exclusion_radius=2)
    expected = cycles_recursive.schedule((23, 30), (5, 4), mask, True, exclusion_radius=2)
    assert recursive.best == expected.best and np.array_equal(recursive.surface, expected.surface)
    window = window_variant(3).schedule((23, 30), (5, 4), mask, False, exclusion_radius=2)
    expected = cycles_window.schedule((23, 30), (5, 4), 3, mask, False, exclusion_radius=2)
    assert window.best == expected.best and np.array_equal(window.surface, expected.surface)
    assert window.best != recursive.best
