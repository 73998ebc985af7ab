"""The modal-integral order a scene needs, chosen per flexible body, and the warning for a spinning body
modelled without its geometric stiffness ("model no more than a scene needs", issue 28 items 3 and 4).

A flexible body's mass matrix ``M(eta)`` (:mod:`dynamics.flexible_body`) couples its modes to the motion of
its reference frame at order 0 only through the constant participation factors (for free-free modes: not
at all); the rotation of the frame enters the modes through the first-order terms (Coriolis and
centrifugal coupling, relative size ``Omega / omega_1`` against the modes' own dynamics, Omega the body's
angular rate, omega_1 its lowest elastic frequency: of its modes, or held at its interface for a component mode
set, ``FlexibleBodyData.lowest_frequency_hz``) and the second-order ones (spin softening and the changes of
the rotational inertia, relative size ``(Omega / omega_1)^2``). The terms of nodes with rotary inertia that
turn with the nodes' elastic rotations (G1, F2, G2) are relative corrections of the size of those rotations.
For a body with ``order="auto"`` :func:`resolve_modal_orders` estimates these sizes from the scene at its
initial state (the body's angular rate, its hinges: a locked chain to the ground cannot turn it, a prescribed
hinge turns it at rates not known before the run) and keeps a term where its estimate exceeds the stated
tolerance:

====================================================  ==========================================
scene (per body, tolerance tol = 1e-3 by default)     order kept
====================================================  ==========================================
cannot rotate (locked to the ground, prismatic)       0
Omega / omega_1 <= tol                                0
(Omega / omega_1)^2 <= tol                            1
above, or driven by a prescribed hinge                2
====================================================  ==========================================

and leaves G1, F2, G2 out when their estimated relative size, the node rotations of the static centrifugal
deflection at Omega (``|lambda_j eta|`` with ``eta_r = Omega^2 |J1_r| / k_r``) times the share of the nodes'
rotary inertia in that deflection's modal mass, stays below the tolerance (never under a prescribed hinge). Each
choice is said in ``system.notes`` (the run summary and ``flexshell check`` print them) with the figures it rests on; the assumption it cannot check (a scene that spins the body faster later, e.g. by its
actuators) is named there, and an explicit order overrides it.

Geometric stiffening (item 4): a body whose file has no geometric stiffness (``fem2modal`` without
``--geometric-stiffness``, the default: the 100k-DOF plate's geometric stiffness costs more than its modes,
docs/geometric_stiffening.md) misses the centrifugal stiffening of a spin, an error of relative size
``(Omega / omega_1)^2`` in its frequencies (95 % on the chordwise mode of a cantilever at Omega_bar = 10).
:func:`stiffening_warnings` names every body spinning with ``(Omega / omega_1)^2`` above 1e-3 without it, with
the ratio and the flag that adds it.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass

import numpy as np

from dynamics.hinges import hinge

TOLERANCE = 1e-3
"""The relative size below which a term of M(eta) is left out by ``order="auto"``."""
STIFFENING_RATIO = 1e-3
"""``(Omega / omega_1)^2`` above which a spinning body without geometric stiffness is warned about."""


@dataclass(frozen=True)
class ModalOrderChoice:
    """What ``order="auto"`` chose for one body and why (one line, with the figures)."""

    body: str
    order: int
    omit: tuple
    reason: str


def _rates(system, q, u):
    """Per body: a bound on the magnitude of its angular velocity (the sum of the angular rates of the hinges
    between it and the ground: revolute ``|u|``, U-joint ``|u1| + |u2|``, spherical and free ``|omega|``), the
    names of prescribed hinges on that path, and whether any hinge on it can turn the body."""
    out = []
    for i in range(system.nbodies):
        prescribed, turns, omega = [], False, 0.0
        j = i
        while j >= 0:
            sl = system.u_slices[j]
            record = hinge(system.hinge_names[j])
            rates = np.asarray(u[sl.start:sl.start + record.nu], dtype=float)
            if np.any(system.prescribed_dofs[sl.start:sl.start + record.nu]):
                prescribed.append(system.joint_names[j])
            turns |= record.rotation != "none"
            if record.rotation == "axes":
                omega += float(np.abs(rates).sum())
            elif record.rotation in ("point", "free"):
                omega += float(np.linalg.norm(rates[:3]))
            j = system.parents[j]
        out.append((omega, prescribed, turns))
    return out


def _node_term_size(data, omega):
    """``(theta, share)``: the node rotations (rad) of the static centrifugal deflection at the rate ``omega``
    (``eta_r = omega^2 |J1_r| / k_r``, the first-order centrifugal modal load over the modal stiffness;
    ``max_j sum_r |lambda_jr| |eta_r|`` over the grids), and the share of the nodes' rotary inertia in the
    modal mass of that deflection (``sum_r w_r lambda_r' J lambda_r / G0_rr``, ``w`` the deflection's modal
    weights; 1 when the body has no per-node data). The terms G1, F2, G2 change the modal inertia by about
    ``theta`` times ``share``."""
    terms = data.mass_terms()
    if terms.R1 is None:
        return 0.0, 1.0
    load = 0.5 * np.linalg.norm(terms.R1[:, :3, :3], ord=2, axis=(1, 2)) * omega ** 2
    eta = load / np.abs(np.diag(np.asarray(data.stiffness)))
    lam = np.linalg.norm(np.asarray(data.grid_shapes)[:, :3, :], axis=1)  # (grids, n)
    theta = float((lam @ eta).max(initial=0.0))
    nodes = data.node_inertia
    if nodes is None or not np.any(eta):
        return theta, 1.0
    rotary = np.einsum("jar,jab,jbr->r", nodes.shapes[:, :3], nodes.inertia, nodes.shapes[:, :3])
    mass = np.abs(np.diag(np.asarray(data.M0)[6:, 6:]))  # zero for quasi-static modes: no inertia to share
    share = np.divide(rotary, mass, out=np.zeros_like(rotary), where=mass > 0.0)
    return theta, float(np.abs(eta) @ share / np.abs(eta).sum())


def _choose(name, data, omega, prescribed, turns, tolerance):
    omega1 = 2.0 * np.pi * data.lowest_frequency_hz
    nodal = ("G1", "F2", "G2")
    if not turns:
        return ModalOrderChoice(name, 0, (), "modal integrals order 0 (auto): no hinge between it and the ground "
                                "turns it, so no term of order 1 or 2 acts")
    if prescribed:
        return ModalOrderChoice(name, 2, (), f"modal integrals order 2 (auto): prescribed hinge(s) "
                                f"{', '.join(repr(p) for p in prescribed)} turn it at rates not known before the run")
    ratio = omega / omega1
    figures = (f"angular rate at most {omega:.3g} rad/s in the initial state, {ratio:.3g} of its first frequency "
               f"{omega1 / (2 * np.pi):.4g} Hz")
    if ratio <= tolerance:
        return ModalOrderChoice(name, 0, (), f"modal integrals order 0 (auto): {figures} (terms of order 1 below "
                                f"{tolerance:g}; a scene that turns it faster later should set "
                                f"modal_integrals_order)")
    order = 1 if ratio ** 2 <= tolerance else 2
    theta, share = _node_term_size(data, omega)
    present = set(data.node_inertia.terms if data.node_inertia is not None else ()) | set(data.mass_terms().present())
    omit = tuple(t for t in nodal[:1 if order == 1 else 3] if t in present) if theta * share <= tolerance else ()
    left = (f"; node rotations of about {theta:.2g} rad under that spin, rotary inertia {share:.2g} of the modal "
            f"mass: terms {', '.join(omit)} left out" if omit else "")
    return ModalOrderChoice(name, order, omit, f"modal integrals order {order} (auto): {figures}{left}")


def stiffening_warnings(system, q, u, ratio=STIFFENING_RATIO):
    """One message per flexible body whose file has no geometric stiffness and whose angular rate Omega at ``q``,
    ``u`` gives ``(Omega / omega_1)^2`` above ``ratio``: the body, the ratio and the flag (module docstring). A
    body whose file has it but whose scene switches it off (``geometric_stiffening: false``) chose so."""
    messages = []
    for i, (omega, _, _) in enumerate(_rates(system, q, u)):
        data = system.definitions[0][i].flexible
        if data is None or data.n_modes == 0 or data.stiffness_available:  # with it, or switched off on purpose
            continue
        r = (omega / (2.0 * np.pi * data.lowest_frequency_hz)) ** 2
        if r > ratio:
            messages.append(f"body '{system.body_names[i]}' spins at {omega:.3g} rad/s, (Omega/omega_1)^2 = {r:.3g} "
                            f"above {ratio:g}, without the centrifugal stiffening (its body file has no geometric "
                            f"stiffness: regenerate it with `flexshell fem2modal ... --geometric-stiffness`): its "
                            f"frequencies are off by about that ratio")
    return messages


def resolve_modal_orders(system, q, u, tolerance=TOLERANCE):
    """``(system, choices)``: the system with every ``order="auto"`` body at the order the scene at ``q``, ``u``
    needs (recompiled when one differs from what it was compiled with; the layout of ``q`` and ``u`` is
    unchanged) and the :class:`ModalOrderChoice` made for each. The choices are recorded in the system's notes,
    and :func:`stiffening_warnings` are issued as warnings and recorded there too."""
    if not system.is_flexible:
        return system, []
    bodies, nodes, gravity = system.definitions
    rates = _rates(system, np.asarray(q, dtype=float), np.asarray(u, dtype=float))
    choices, changed = [], False
    new_bodies = list(bodies)
    for i, b in enumerate(bodies):
        if b.flexible is None or b.auto_order is None:
            continue
        choice = _choose(b.name, b.flexible, *rates[i], tolerance)
        choices.append(choice)
        data = b.auto_order(choice.order, choice.omit)
        new_bodies[i] = dataclasses.replace(b, flexible=dataclasses.replace(data, note=choice.reason))
        changed = True
    if changed:
        system = type(system).from_definitions(new_bodies, list(nodes), gravity, solver=system.requested_solver)
    messages = stiffening_warnings(system, q, u)
    for message in messages:
        warnings.warn(message, UserWarning, stacklevel=2)
    if messages:
        system = system.with_notes(f"warning: {m}" for m in messages)
    return system, choices
