"""Hostile patch files for lost correlate: words in cells, other separators, ragged rows, complex and text arrays."""

from __future__ import annotations

import numpy as np
import pytest

from lost.host.io.patch import read_patch


def test_a_word_in_a_patch_csv_is_refused_with_its_line_and_column(tmp_path):
    path = tmp_path / "patch.csv"
    path.write_text("10,11,12\n13,deep,15\n")
    with pytest.raises(ValueError, match=r"patch.csv: line 2, column 2 is 'deep', not a depth"):
        read_patch(path)


@pytest.mark.parametrize("sep", [";", "\t", " ", ","])
def test_semicolon_tab_space_and_comma_patches_read_the_same(tmp_path, sep):
    path = tmp_path / "patch.csv"
    no_beam = "nan" if sep == " " else ""  # whitespace has no empty cell
    path.write_text(f"# a comment\n10{sep}11{sep}12\n13{sep}{no_beam}{sep}15\n")
    patch = read_patch(path)
    assert patch.shape == (2, 3) and patch[0, 2] == 12.0 and np.isnan(patch[1, 1]) and patch[1, 2] == 15.0


def test_a_ragged_patch_is_refused_naming_the_line(tmp_path):
    path = tmp_path / "patch.csv"
    path.write_text("10,11,12\n13,14\n")
    with pytest.raises(ValueError, match=r"patch.csv: line 2 has 2 cells where the first row has 3"):
        read_patch(path)


@pytest.mark.parametrize(("values", "what"), [(np.ones((3, 3), complex), "complex numbers"), (np.array([["1", "2"], ["3", "4"]]), "<U1 values, not numbers")])
def test_complex_and_text_arrays_are_refused_before_any_arithmetic(tmp_path, values, what):
    np.save(tmp_path / "patch.npy", values)
    with pytest.raises(ValueError, match=f"patch.npy holds {what}"):
        read_patch(tmp_path / "patch.npy")


def test_a_one_dimensional_patch_is_refused_with_its_shape(tmp_path):
    np.save(tmp_path / "patch.npy", np.ones(5))
    with pytest.raises(ValueError, match=r"patch.npy holds an array of shape \(5,\); a patch is 2-D"):
        read_patch(tmp_path / "patch.npy")
