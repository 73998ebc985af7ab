"""OP4 matrix files (NASTRAN output4) through pyNastran's OP4 reader and writer.

Reading accepts ASCII and binary files with dense or sparse matrices (e.g. KGG, MGG written by
NASTRAN with a DMAP OUTPUT4); every matrix comes back as a float64 ``scipy.sparse.csr_matrix``.
Writing produces ASCII sparse double-precision matrices (pyNastran 1.3 cannot write sparse
binary), which NASTRAN's INPUTT4 and pyNastran read back bit for bit.
"""

from __future__ import annotations

import os

import numpy as np
import scipy.sparse as sp

# NASTRAN OP4 form codes: 1 square, 2 rectangular, 6 symmetric
_FORM_SQUARE, _FORM_RECTANGULAR, _FORM_SYMMETRIC = 1, 2, 6


def read_op4_matrices(path) -> dict:
    """{name: csr_matrix} for every matrix in ``path``."""
    from pyNastran.op4.op4 import read_op4

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"OP4 file not found: {path}")
    try:
        raw = read_op4(path, debug=False)
    except Exception as exc:
        raise ValueError(f"{path}: pyNastran could not read the OP4 file: {exc}") from exc
    out = {}
    for name, value in raw.items():
        matrix = value[1] if isinstance(value, tuple) else getattr(value, "data", value)
        if np.iscomplexobj(matrix.data if sp.issparse(matrix) else matrix):
            raise ValueError(f"{path}: matrix {name} is complex; real matrices expected")
        out[name.strip().upper()] = sp.csr_matrix(matrix, dtype=np.float64)
    return out


def write_op4_matrices(path, matrices: dict) -> None:
    """Write {name: matrix} as ASCII sparse double-precision OP4."""
    from pyNastran.op4.op4 import OP4

    payload = {}
    for name, M in matrices.items():
        C = sp.coo_matrix(M, dtype=np.float64)
        if C.shape[0] == C.shape[1]:
            symmetric = abs(C - C.T).max() == 0.0 if C.nnz else True
            form = _FORM_SYMMETRIC if symmetric else _FORM_SQUARE
        else:
            form = _FORM_RECTANGULAR
        payload[name.upper()] = (form, C)
    OP4(debug=False).write_op4(os.fspath(path), payload, is_binary=False, precision="double")
