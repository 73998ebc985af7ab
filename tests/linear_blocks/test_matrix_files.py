"""State-space matrices from HDF5, .mat and .npz files (shell/linear/matrix_files.py): read back exactly, and
every bad file refused with the file, the key, what was expected and what was given."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from scipy.io import savemat

from shell.linear.matrix_files import read_state_space
from shell.linear.system import LinearSystem, LinearSystemError

A = np.array([[0.9, 0.1], [-0.2, 0.7]])
B = np.array([[1.0], [0.5]])
C = np.array([[1.0, -1.0], [0.0, 2.0]])
D = np.array([[0.0], [0.1]])


def _write(path, fmt, group=None, **matrices):
    if fmt == "npz":
        np.savez(path, **{(f"{group}/{k}" if group else k): v for k, v in matrices.items()})
    elif fmt == "mat":
        savemat(path, {(f"{group}/{k}" if group else k): v for k, v in matrices.items()})
    else:
        with h5py.File(path, "w") as f:
            node = f.create_group(group) if group else f
            for key, value in matrices.items():
                if key == "sample_time":
                    node.attrs[key] = value
                else:
                    node.create_dataset(key, data=value)


@pytest.mark.parametrize("fmt", ["h5", "mat", "npz"])
def test_matrices_read_back_exactly(tmp_path, fmt):
    path = tmp_path / f"plant.{fmt}"
    _write(path, fmt, A=A, B=B, C=C, D=D, sample_time=0.05)
    system = read_state_space(path)
    for key, value in zip("ABCD", (A, B, C, D)):
        np.testing.assert_array_equal(getattr(system, key), value)
    assert system.sample_time == 0.05
    assert system.input_names == ("u[0]",) and system.output_names == ("y[0]", "y[1]")
    stable = read_state_space(path, require_stable="the filter")
    assert stable.is_stable()


@pytest.mark.parametrize("fmt", ["h5", "npz"])
def test_a_group_selects_one_of_several_systems(tmp_path, fmt):
    path = tmp_path / f"filters.{fmt}"
    _write(path, fmt, group="roll", A=A, B=B, C=C, D=D)
    assert read_state_space(path, group="roll").sample_time is None
    with pytest.raises(LinearSystemError, match=r"filters.(h5|npz): no group 'pitch'; groups: \['roll'\]"):
        read_state_space(path, group="pitch")


@pytest.mark.parametrize("fmt", ["h5", "mat", "npz"])
@pytest.mark.parametrize("matrices, message", [
    (dict(A=A, B=B, C=C), r"no D; expected the matrices A, B, C, D; the file holds: A, B, C"),
    (dict(A=A[:, :1], B=B, C=C, D=D), r"A: expected a square matrix, given shape \(2, 1\)"),
    (dict(A=A, B=np.ones((3, 1)), C=C, D=D), r"B: expected 2 rows \(the states of A\), given shape \(3, 1\)"),
    (dict(A=A, B=B, C=np.ones((2, 3)), D=D), r"C: expected 2 columns"),
    (dict(A=A, B=B, C=C, D=np.zeros((1, 1))), r"D: expected shape \(2, 1\) \(outputs of C x inputs of B\), given \(1, 1\)"),
    (dict(A=A, B=B, C=C, D=np.array([[0.0], [np.nan]])), r"D: entry \[1, 0\] is nan \(1 entries are not finite\)"),
    (dict(A=A, B=B, C=C, D=D, sample_time=-0.1), r"sample_time: expected a period > 0 s"),
])
def test_bad_matrices_are_refused_with_file_and_key(tmp_path, fmt, matrices, message):
    path = tmp_path / f"bad.{fmt}"
    _write(path, fmt, **matrices)
    with pytest.raises(LinearSystemError, match=message) as info:
        read_state_space(path)
    assert str(info.value).startswith(str(path))


def test_unstable_system_refused_where_a_stable_one_is_required(tmp_path):
    path = tmp_path / "estimator.npz"
    _write(path, "npz", A=np.array([[1.0, 0.1], [0.0, 0.95]]), B=B, C=C, D=D, sample_time=0.1)
    assert read_state_space(path).sample_time == 0.1  # accepted where stability is not required
    with pytest.raises(LinearSystemError, match=r"estimator.npz: A: the estimator must be stable; 1 eigenvalue\(s\) "
                                                r"on or outside the unit circle: 1"):
        read_state_space(path, require_stable="the estimator")
    continuous = tmp_path / "lead.h5"
    _write(continuous, "h5", A=np.array([[0.5]]), B=[[1.0]], C=[[1.0]], D=[[0.0]])
    with pytest.raises(LinearSystemError, match="in the closed right half-plane: 0.5"):
        read_state_space(continuous, require_stable="the filter")


def test_file_level_refusals(tmp_path):
    with pytest.raises(LinearSystemError, match="no such file"):
        read_state_space(tmp_path / "missing.h5")
    text = tmp_path / "plant.csv"
    text.write_text("1,2\n")
    with pytest.raises(LinearSystemError, match=r"expected an HDF5 \(.h5, .hdf5\), MATLAB \(.mat\) or numpy \(.npz\)"):
        read_state_space(text)
    fake = tmp_path / "plant.h5"
    fake.write_text("not hdf5")
    with pytest.raises(LinearSystemError, match="cannot read as HDF5"):
        read_state_space(fake)


def test_linear_system_checks_names_and_sample_time():
    with pytest.raises(LinearSystemError, match="input names: expected 1 names, given 2"):
        LinearSystem(A, B, C, D, input_names=("a", "b"))
    with pytest.raises(LinearSystemError, match="sample_time"):
        LinearSystem(A, B, C, D, sample_time=True)
