"""The engine's compiled algorithms: one augmented-body recursion for rigid and flexible bodies (numba).

Every body k carries an *augmented* velocity ``x_k = [V_k; eta_dot_k]`` of size ``6 + n_k`` (rigid bodies:
``n_k = 0``). With ``u_k = [hinge rates; eta_dot_k]`` the kinematics of the tree read

    x_k = P_k x_p + H_k u_k,   P_k = [X_k [I, Psi_k]; 0],   H_k = [[S_k, -Pc_k], [0, I]]

where ``X_k`` is the rigid motion transform from the parent frame to body k (through the deformed pose of
the parent node the hinge is attached to, when the parent is flexible), ``Psi_k`` (6 x n_p) the spatial
velocity of that node per unit modal rate of the parent (:func:`dynamics.flexible_kernels.node_deformation`),
``S_k`` the hinge's motion subspace, and ``Pc_k`` (6 x n_k) the ``Psi`` of a node of body k itself when the
hinge's outboard frame sits on it (``child_grid``; zero otherwise). Differentiating gives
``xdot_k = P_k xdot_p + H_k udot_k + c_k`` with the velocity-product term

    c_k = [X_k w' + c_J + V_k x (X_k w + S u - w_c) + (X_k w) x (S u - w_c) + w_c x (S u) - w'_c; 0],
    w = Psi_k eta_dot_p,  w_c = Pc_k eta_dot_k,  w', w'_c the velocity products of d/dt (Psi eta_dot)

(Featherstone, *Rigid Body Dynamics Algorithms* (RBDA), 2008, eqs. 2.39-2.43, for a parent frame that
itself moves relative to the parent body). Each body's equations ``F_k = M_k(eta) xdot_k + b_k`` follow
from its kinetic energy (:mod:`dynamics.flexible_kernels`; a rigid body has ``M = I``,
``b = V x* I V``). The algorithms are the rigid-body ones run in these augmented spaces (Jain, *Robot and
Multibody Dynamics*, 2011, ch. 13: the flexible-body ABA):

* :func:`forward_dynamics` - articulated-body algorithm (RBDA Table 7.1; :mod:`~dynamics.kernels.articulated_body`)
  with prescribed hinge DOFs (their known accelerations enter the bias, their forces come from ``IA a + pA``,
  RBDA sec. 9.3). A flexible body's modal DOFs are eliminated before its hinge DOFs by a Schur complement whose
  modal block, ``E' = G + L' Q L``, is the modal mass ``G`` plus updates of rank 6 per node that children hang
  from (and 12 for a hinge on a node of the body), so ``E'^-1`` comes from the precomputed ``G0^-1`` and a small
  dense solve (Woodbury): O(n^2) per body (O(n) with a diagonal ``G0``), see
  :mod:`dynamics.kernels.modal_condensation`. A modal mass that depends on eta through the nodes' rotary
  inertia is refined against ``G0`` (O(N_r n) per pass); tables of G1 or G2 make it factored per call, O(n^3);
* :func:`forward_dynamics_dense` - the same accelerations from ``M(q) udot = tau - h`` (CRBA, RNEA and a
  dense Cholesky factorization): chosen at compile time when it is cheaper (``MultibodySystem.solver``);
* :func:`inverse_dynamics` - recursive Newton-Euler (RBDA Table 5.1; :mod:`~dynamics.kernels.newton_euler`);
* :func:`mass_matrix` - composite-rigid-body algorithm (RBDA Table 6.2; :mod:`~dynamics.kernels.composite_body`),
  exactly symmetric;
* :func:`node_kinematics` and :func:`node_kinematics_after_dynamics` - pose, spatial velocity and classical
  acceleration of frames on (deforming) bodies (:mod:`~dynamics.kernels.node_frames`);
* :func:`energy_momentum` - kinetic and potential energy, linear and angular momentum in the world
  (:mod:`~dynamics.kernels.energy`).

A body without modal data whose hinge is not on a deforming node (topology column ``GENERAL`` = 0) runs the
6 x 6 rigid-body code (the rigid fast path); every other body runs the augmented code, which reduces to
the same equations for zero modes (``tests/dynamics/test_zero_modes.py`` compares the two to round-off).
Gravity enters as a fictitious upward acceleration of the ground, ``a_0 = [0; -g]`` (RBDA sec. 5.3).
External forces: per body (about the body origin, body axes) and per node (node axes, at the deformed
node).

Data (built by :class:`dynamics.system.MultibodySystem`, columns and offsets in :mod:`dynamics.layout`):
``topology`` (one int row per body), ``nodes`` (one int row per node), ``joint_rot``/``joint_vec`` (hinge
frames and axes), ``params`` (every other float of the description: ground acceleration, body inertias, modal
data, node frames and mode shapes) and the workspace ``ws_rot``, ``ws_vec``, ``ws_mat`` (6 x 6 quantities per
body) and ``pool`` (everything sized by modes). Kernels write their results into output arguments and
allocate nothing.

Modules, one per algorithm: :mod:`~dynamics.kernels.kinematics` (poses, velocities, biases, accelerations,
coordinate rates), :mod:`~dynamics.kernels.body_terms` (per-body inertia and forces),
:mod:`~dynamics.kernels.modal_condensation` (the modal elimination), :mod:`~dynamics.kernels.articulated_body`,
:mod:`~dynamics.kernels.newton_euler`, :mod:`~dynamics.kernels.composite_body`,
:mod:`~dynamics.kernels.node_frames`, :mod:`~dynamics.kernels.energy`, :mod:`~dynamics.kernels.node_inertia` (the
terms of nodes with rotary inertia) and :mod:`~dynamics.kernels.small_linalg` (the few-by-few solves). This package
names the algorithms and the layout's columns (``dynamics.kernels.forward_dynamics``, ``dynamics.kernels.FLEXIBLE``).
"""
from dynamics.kernels.articulated_body import forward_dynamics
from dynamics.kernels.body_terms import rigid_bias_add
from dynamics.kernels.composite_body import mass_matrix
from dynamics.kernels.dense_forward import forward_dynamics_dense
from dynamics.kernels.energy import energy_momentum
from dynamics.kernels.kinematics import accumulate_world_poses, coordinate_rates, initialize_workspace
from dynamics.kernels.newton_euler import inverse_dynamics
from dynamics.kernels.node_frames import node_kinematics, node_kinematics_after_dynamics
from dynamics.layout import *  # noqa: F401,F403  (the column names, as dynamics.kernels.NAME)

__all__ = ["accumulate_world_poses", "coordinate_rates", "energy_momentum", "forward_dynamics",
           "forward_dynamics_dense", "initialize_workspace", "inverse_dynamics", "mass_matrix", "node_kinematics",
           "node_kinematics_after_dynamics", "rigid_bias_add"]
