"""Which modes of a flexible-body file a scene keeps: by index, by frequency cutoff, or both.

A body file carries every mode its FE model was reduced to (``flexshell fem2modal --modes/--cutoff``); a scene
often needs only those in its control bandwidth. Dropping the modes above a frequency ``f_max`` is the
classical modal truncation: the retained coordinates and their modal integrals are exactly those of the
file (the selection is a restriction of the mass-normalized basis, TM-2020-5008164 eq. E.1.19, so no
re-orthogonalization is needed), and the cost of the engine and the stiffness seen by an explicit
integrator (``h omega_max``) fall with the top retained mode.

Rules (the scenario key ``max_frequency:`` of a flexible body and the ``max_frequency=`` argument use this):

* ``max_frequency`` keeps the modes whose body-file frequency is at or below it (``f <= f_max``, as
  ``fem2modal --cutoff`` does). These are the frequencies of the body alone with the boundary conditions of
  its mode set (free-free, or fixed-interface/normalized component modes), not the system modes of the
  assembled scene.
* ``modes`` and ``max_frequency`` together keep the listed modes that are below the cutoff, in the listed
  order; listed modes that the cutoff removes are named in a warning.
* Quasi-static modes (infinite frequency: massless interface DOFs of normalized component modes,
  :mod:`dynamics.flex.component_modes`) are static flexibility, not dynamics: a cutoff keeps them.
* A cutoff that removes every mode is refused (a flexible body needs at least one mode; make it a rigid
  body instead); so are a non-positive cutoff, repeated indices and indices outside the file.
"""

from __future__ import annotations

import warnings

import numpy as np


def select_modes(frequencies_hz, modes=None, max_frequency=None):
    """Indices (int64, ascending or in the order of ``modes``) of the modes to keep; see the module docstring.

    ``frequencies_hz``: the body file's modal frequencies (Hz), one per mode. ``modes``: indices into them,
    or None for all. ``max_frequency``: cutoff in Hz, or None for none.
    """
    frequencies = np.asarray(frequencies_hz, dtype=np.float64)
    if frequencies.ndim != 1 or frequencies.size == 0:
        raise ValueError(f"select_modes: frequencies_hz must be a non-empty 1-D array, got shape {frequencies.shape}")
    n = frequencies.size
    if modes is None:
        keep = np.arange(n, dtype=np.int64)
    else:
        given = list(modes)
        if not given or not all(isinstance(m, (int, np.integer)) and not isinstance(m, bool) for m in given):
            raise ValueError(f"select_modes: modes must be a non-empty list of mode indices, got {modes!r}")
        keep = np.asarray(given, dtype=np.int64)
        outside = keep[(keep < 0) | (keep >= n)]
        if outside.size:
            raise ValueError(f"select_modes: mode indices {outside.tolist()} are outside the body file's "
                             f"{n} modes (0..{n - 1})")
        values, counts = np.unique(keep, return_counts=True)
        if np.any(counts > 1):
            raise ValueError(f"select_modes: mode indices {values[counts > 1].tolist()} are listed more than once")
    if max_frequency is None:
        return keep
    f_max = float(max_frequency)
    if not (f_max > 0.0) or not np.isfinite(f_max):
        raise ValueError(f"select_modes: max_frequency must be a positive, finite frequency in Hz, got "
                         f"{max_frequency!r}")
    below = (frequencies[keep] <= f_max) | np.isposinf(frequencies[keep])
    if not np.any(below):
        which = "of the listed modes " if modes is not None else ""
        raise ValueError(f"select_modes: max_frequency = {f_max:.6g} Hz removes every mode {which}(the lowest "
                         f"is mode {int(keep[np.argmin(frequencies[keep])])} at {frequencies[keep].min():.6g} Hz); "
                         f"raise the cutoff, or model the body as rigid")
    if modes is not None and not np.all(below):
        dropped = keep[~below]
        warnings.warn(f"select_modes: max_frequency = {f_max:.6g} Hz drops the listed modes {dropped.tolist()} "
                      f"(at {np.round(frequencies[dropped], 6).tolist()} Hz)", stacklevel=2)
    return keep[below]
