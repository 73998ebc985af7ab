"""A flexible body's modal stiffness and damping applied as their diagonal when the off-diagonal entries are
round-off (``dynamics.system.MODAL_DIAGONAL_TOLERANCE``), kept whole otherwise, and said in ``summary()``.

References: the same body with the exactly diagonal matrices (the dropped entries must not change anything beyond
their own size), and the elastic force ``K eta + C e`` written out with the coupled matrix (a real coupling must
stay)."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics import layout as L
from dynamics.algorithms import damping_matrix, stiffness_matrix
from dynamics.system import MODAL_DIAGONAL_TOLERANCE, _offdiagonal_ratio

from .random_flexible import flexible_body_data, random_node_model
from .test_flexible_tree import random_state


def _coupled(a, ratio, seed):
    """``a`` (diagonal) plus symmetric off-diagonal entries of exactly ``ratio`` times the geometric mean of their
    diagonal entries (signs random)."""
    rng = np.random.default_rng(seed)
    d = np.sqrt(np.abs(np.diag(a)))
    signs = np.sign(rng.standard_normal(a.shape))
    signs = np.triu(signs, 1)
    signs = signs + signs.T
    return a + ratio * signs * np.outer(d, d)


def _system(stiffness=None, damping=None):
    node_model = random_node_model(6, 4, seed=11, scale=0.2)
    if stiffness is not None:
        node_model.stiffness = stiffness(node_model.stiffness)
    if damping is not None:
        node_model.damping = damping(node_model.damping)
    mb = Multibody(gravity=(0.0, 0.0, 0.0))
    mb.add_flexible_body("panel", None, modal=flexible_body_data(node_model, 1), hinge="free")
    return mb.compile(), node_model


def test_offdiagonal_ratio_is_scale_free():
    K = _coupled(np.diag([1.0, 4.0e4, 9.0e8]), 3e-11, seed=1)
    assert _offdiagonal_ratio(K) == pytest.approx(3e-11, rel=1e-12)
    S = np.diag([1e-3, 1.0, 1e3])  # the same modes scaled: the ratio does not move
    assert _offdiagonal_ratio(S @ K @ S) == pytest.approx(3e-11, rel=1e-12)
    assert _offdiagonal_ratio(np.diag([0.0, 2.0])) == 0.0
    assert _offdiagonal_ratio(np.array([[0.0, 1e-20], [1e-20, 1.0]])) == np.inf


def test_round_off_coupling_is_dropped_said_and_changes_nothing_beyond_itself():
    exact, _ = _system()
    rounded, model = _system(stiffness=lambda K: _coupled(K, 1e-10, seed=2),
                             damping=lambda C: _coupled(C, 2e-10, seed=3))
    i = rounded.body_names.index("panel")
    fx = rounded.topology[i, L.FLEX:]
    assert fx[L.FX_K_DIAGONAL] and fx[L.FX_C_DIAGONAL]
    # what every kernel reads is the diagonal, bit for bit
    np.testing.assert_array_equal(stiffness_matrix(rounded.model), stiffness_matrix(exact.model))
    np.testing.assert_array_equal(damping_matrix(rounded.model), damping_matrix(exact.model))
    summary = rounded.summary()
    assert "modal stiffness applied as its diagonal (largest off-diagonal entry 1.0e-10" in summary
    assert "modal damping applied as its diagonal (largest off-diagonal entry 2.0e-10" in summary
    assert "applied as its diagonal" not in exact.summary()  # exactly diagonal: nothing dropped, nothing said
    q, u, _ = random_state(rounded, np.random.default_rng(4))
    tau = np.zeros(rounded.nu)
    np.testing.assert_array_equal(rounded.forward_dynamics(q, u, tau), exact.forward_dynamics(q, u, tau))


def test_real_coupling_is_kept():
    ratio = 100 * MODAL_DIAGONAL_TOLERANCE
    coupled, model = _system(stiffness=lambda K: _coupled(K, ratio, seed=5),
                             damping=lambda C: _coupled(C, 1e-3, seed=6))
    exact, _ = _system()
    i = coupled.body_names.index("panel")
    fx = coupled.topology[i, L.FLEX:]
    assert not fx[L.FX_K_DIAGONAL] and not fx[L.FX_C_DIAGONAL]
    assert "applied as its diagonal" not in coupled.summary()
    n = model.stiffness.shape[0]
    Kc = stiffness_matrix(coupled.model)
    np.testing.assert_array_equal(Kc[-n:, -n:], model.stiffness)
    # the coupling reaches the accelerations: the difference from the diagonal body is the extra elastic force
    q, u, _ = random_state(coupled, np.random.default_rng(7))
    tau = np.zeros(coupled.nu)
    extra = np.zeros(coupled.nu)
    eta, e = q[-n:], u[-n:]
    extra[-n:] = (model.stiffness - np.diag(np.diag(model.stiffness))) @ eta \
        + (model.damping - np.diag(np.diag(model.damping))) @ e
    # M (a_coupled - a_exact) = -extra: the generalized force of the off-diagonal terms
    delta = coupled.forward_dynamics(q, u, tau) - exact.forward_dynamics(q, u, tau)
    M = coupled.mass_matrix(q)
    np.testing.assert_allclose(M @ delta, -extra, rtol=0, atol=1e-9 * np.abs(extra).max())
    assert np.abs(extra).max() > 1e-8  # the test has something to find
