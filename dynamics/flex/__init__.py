"""FEM-to-modal pipeline (FModal equivalent): NASTRAN bulk data in, HDF5 flexible-body file out.

Entry points: :func:`dynamics.flex.pipeline.fem2modal` (deck -> :class:`ModalBody`),
:func:`dynamics.flex.body_file.write_body_file` / :func:`read_body_file`, and the command line
``flexshell fem2modal``. See docs/fem2modal.md and docs/body_file.md.
"""

from dynamics.flex.body_file import ModalBody, read_body_file, write_body_file
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

__all__ = ["ModalBody", "Fem2ModalOptions", "fem2modal", "read_body_file", "write_body_file"]
