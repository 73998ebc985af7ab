"""The engine's data layout: the columns of its int tables and the offsets inside its float arrays.

A compiled system (:class:`dynamics.system.MultibodySystem`) is a handful of flat arrays that every kernel of
:mod:`dynamics.kernels` reads (Pinocchio's ``Model``/``Data`` split, in arrays numba can take):

* the description, immutable during a run: ``topology`` (one int64 row per body, the ``*`` columns
  below, then per flexible body the ``FX_*`` columns from ``FLEX`` on), ``nodes`` (one int64 row per node,
  ``NODE_*``), ``joint_rot`` (nb, 2, 3, 3) and ``joint_vec`` (nb, 4, 3) (hinge frames and axes: ``INBOARD``,
  ``OUTBOARD``, ``AXIS1``, ``AXIS2``), ``params`` (float64: the ground acceleration at ``GROUND_ACCEL``, the
  bodies' 6 x 6 inertias, modal data, node frames and mode shapes, found through the offsets of the tables);
* the workspace, scratch of one evaluation: ``ws_rot`` (nb, N_ROT, 3, 3), ``ws_vec`` (nb, N_VEC, 6), ``ws_mat``
  (nb, N_MAT, 6, 6) for the 6 x 6 quantities of every body (``ROT_*``, ``VEC_*``, ``MAT_*``), and ``pool``
  (float64) for everything sized by modes: a header (``P_*``), per node that children hang from a slot
  (``SL_*``), per flexible body its blocks (``FX_P_*`` offsets; n-vectors ``PV_*``).

One place for all of them, so that a kernel, the compiler of the layout (:mod:`dynamics.system`) and a test
name the same column the same way. The module's public names are these constants and :func:`view` only
(:mod:`dynamics.kernels` re-exports them).
"""

from numba import njit as _njit

# topology columns (one int64 row per body)
PARENT = 0
HINGE_TYPE = 1
Q_START = 2
NQ_HINGE = 3
U_START = 4
NU_HINGE = 5
N_MODES = 6
N_FREE = 7
N_PRESCRIBED = 8
OUTBOARD_IDENTITY = 9  # 1 when the hinge outboard frame is the body frame (saves a frame product)
GENERAL = 10  # 1: the augmented path (flexible, or hinged on a deforming node); 0: the rigid fast path
INERTIA = 11  # params offset of the constant rigid block M0[:6, :6] (the spatial inertia), 36 numbers
FREE_DOFS = 12  # 6 columns: local indices of the free hinge DOFs
PRESCRIBED_DOFS = 18  # 6 columns: local indices of the prescribed hinge DOFs
PARENT_NODE = 24  # the parent's node the hinge is attached to (-1: the parent frame)
OUTBOARD_NODE = 25  # the node of the body itself that carries the hinge's outboard frame (-1: the body frame)
FLEXIBLE = 26  # 1: the body has modal data (possibly zero modes) and the FLEX columns describe it
FIRST_SLOT = 27  # first node of this body that children hang from (chained by NODE_NEXT_SLOT), or -1
FLEX = 28  # the flexible-body columns FX_* (below) start here

# flexible-body columns, relative to FLEX (offsets: -1 when the term is absent)
FX_ORDER = 0
FX_M0RE = 1  # params: M0[:6, 6:] (6 x n)
FX_G0 = 2  # params: M0[6:, 6:] (n x n), the constant modal mass
FX_R1 = 3  # params: (n, 6, 6) first-order rigid/rigid block
FX_C1 = 4  # params: (n, C1_ROWS, n) first-order rigid/modal block
FX_C1_ROWS = 5  # 3 when only the rotational rows are non-zero (E1 = 0: no CG offsets), else 6
FX_G1 = 6  # params: (n, n, n) first-order modal/modal block
FX_J2 = 7  # params: (n, n, 3, 3)
FX_F2 = 8  # params: (n, n, 3, n)
FX_G2 = 9  # params: (n, n, n, n)
FX_K = 10  # params: stiffness (n x n)
FX_K_DIAGONAL = 11  # 1 when the stiffness is diagonal
FX_C = 12  # params: damping (n x n)
FX_C_DIAGONAL = 13
FX_GINV_KIND = 14  # how G^-1 is applied: GINV_DIAGONAL, GINV_DENSE (constant G) or GINV_FACTORED
FX_GINV = 15  # params: 1 / diag(G0) (n) or G0^-1 (n x n); -1 when factored
FX_ZM0 = 16  # params: M0[:6, 6:] G0^-1 (6 x n) for a constant G; -1 when factored
FX_P_MRE = 17  # pool: M_re(eta) (6 x n); the coupling block of the composite inertia in the CRBA
FX_P_MDRE = 18  # pool: dM_re/dt (6 x n)
FX_P_BP = 19  # pool: B' = IA_re - IA_rr Pc (6 x n)
FX_P_ZM = 20  # pool: M_re G^-1 (6 x n), then B' G^-1
FX_P_W = 21  # pool: W' = B' E'^-1 (6 x n)
FX_P_VEC = 22  # pool: N_PV n-vectors (PV_*)
FX_P_G = 23  # pool: G(eta), its Cholesky factor, or the composite modal inertia (n x n)
FX_P_F = 24  # pool: force columns of the CRBA (6 x (6 + n))
FX_P_SMALL = 25  # pool: the Woodbury system (V and Q r x r, [C | rhs] r x (r + 7), U and Z r x n)
FX_RANK = 26  # r = 6 (child attachment nodes) + 12 (when the hinge sits on a node of the body)
FX_P_MRR = 27  # pool: M_rr(eta) (6 x 6)
FX_P2 = 28  # params: (n, n, 3) second-order mass-centre shift of geometric stiffening (ModalMassTerms.P2)
FX_NODES = 29  # params: the node-inertia data (dynamics.kernels.node_inertia.node_params), -1 when none
FX_NODE_COUNT = 30  # how many nodes with rotary inertia or CG offsets carry terms of M(eta)
FX_NODE_TERMS = 31  # which terms they carry: a sum of NODE_G1, NODE_G2, NODE_F2
FX_P_NODES = 32  # pool: theta_j = lambda_j eta, u_j = gamma_j eta and scratch of each such node (NODE_STATE per node)
FX_REFINE = 33  # > 0: G(eta) = G0 + node terms, refined against the constant G0 (GINV_KIND of G0) for at
#                most this many passes (the cost of factoring G(eta) instead); 0: not refined
FX_MASS_NODES = 34  # params: the node data of the terms C1, J2 over the nodes (dynamics.kernels.node_mass), -1: none
FX_MASS_NODE_COUNT = 35  # how many nodes (every node with mass or inertia)
FX_MASS_NODE_TERMS = 36  # which terms they carry: a sum of MASS_C1, MASS_J2 (then absent as tables)
FX_P_MASS_NODES = 37  # pool: scratch of those nodes (dynamics.kernels.node_mass.MASS_NODE_STATE per node)
N_FX = 38

# n-vectors of a flexible body in the pool (FX_P_VEC + k n)
PV_FORCE = 0  # modal bias minus applied modal forces (ABA) / modal body force (RNEA)
PV_RHS = 1  # G^-1 d (ABA)
PV_Y = 2  # E'^-1 d (ABA), kept for the acceleration pass
PV_TMP = 3
PV_DG = 4  # (G(eta) - G0) etaddot of the current refinement iterate (ABA)
PV_PREV = 5  # the modal accelerations of the previous refinement iterate
N_PV = 6

# the terms of M(eta) summed over nodes (FX_NODE_TERMS bits; their data: dynamics.kernels.node_inertia.node_params)
NODE_G1 = 1
NODE_G2 = 2
NODE_F2 = 4

# the terms C1 and J2 summed over every node (FX_MASS_NODE_TERMS bits; data: dynamics.kernels.node_mass)
MASS_C1 = 1
MASS_J2 = 2

# how G^-1 is applied
GINV_DIAGONAL = 0
GINV_DENSE = 1
GINV_FACTORED = 2

TOPOLOGY_COLUMNS = FLEX + N_FX

# node table columns (one int64 row per node)
NODE_BODY = 0
NODE_FRAME = 1  # params offset: node -> body rotation R0 (9, row major), then position l0 (3)
NODE_SHAPE = 2  # params offset of Pi = [lambda; gamma] (6 x n) on a flexible body, -1 on a rigid one
NODE_SHAPE_GINV = 3  # params offset of Pi G0^-1 (6 x n): slot nodes of constant-G bodies, else -1
NODE_SLOT = 4  # pool offset of the node's slot (children hang from it, or it carries the body's hinge)
NODE_NEXT_SLOT = 5  # the next child-attachment node of the same body, or -1
NODE_COLUMNS = 6

# params: [0:6] ground acceleration, then the bodies' 6 x 6 inertias, then modal data and node frames
GROUND_ACCEL = 0

# a slot: the deformed node (R, l), w = Psi eta_dot, w', the children's articulated inertia Y and force
# g summed in this node's body axes, then Psi (6 x n) and Z = Psi G^-1 (6 x n)
SL_R = 0
SL_L = 9
SL_W = 12
SL_WD = 18
SL_Y = 24
SL_G = 60
SL_PSI = 66

# pool header: scratch of the node loops, then the Psi of one node (6 x nmax), then body blocks
P_TMP83 = 0  # (8, 3) for node_deformation
P_R = 24
P_L = 33
P_W = 36
P_WD = 42
P_V1 = 48
P_V2 = 54
P_ZERO = 60  # 6 zeros: the ground acceleration of node kinematics
P_T33 = 66  # 3 x 3
P_REFINEMENTS = 75  # refinement passes of the last forward dynamics (dynamics.kernels.articulated_body)
POOL_HEADER = 80

# joint_rot slots: (nb, 2, 3, 3) and joint_vec slots: (nb, 4, 3)
INBOARD = 0  # rotation R_PF / position of F in the parent frame (or in the parent node's frame)
OUTBOARD = 1  # rotation R_BM / position of M in the body frame (or in the outboard node's frame)
AXIS1 = 2
AXIS2 = 3

# workspace slots
ROT_PB = 0  # body -> parent rotation
ROT_FM = 1
ROT_1 = 2  # U-joint scratch, then R_PF of a hinge on a deforming parent node
ROT_2 = 3
ROT_WB = 4  # body -> world rotation
ROT_BM = 5  # outboard frame on a deforming node of the body
N_ROT = 6

VEC_V = 0  # spatial velocity of the body
VEC_C = 1  # velocity-product (and prescribed) bias acceleration
VEC_P = 2  # articulated bias force pA (ABA) / body force f (RNEA)
VEC_A = 3  # spatial acceleration
VEC_D = 4  # joint-space residual d (ABA)
VEC_POS = 5  # [0:3] position of the body origin in the parent, [3:6] p_FM
VEC_AUX = 6  # hinge velocity S u, then ABA's pa
VEC_WPOS = 7  # [0:3] body origin in the world, [3:6] p_PF on a deforming parent node
VEC_XW = 8  # X w: the parent node's velocity relative to the parent, in body axes
VEC_WC = 9  # w_c: the outboard node's velocity relative to the body
VEC_PBM = 10  # [0:3] p_BM of an outboard frame on a deforming node
VEC_P0 = 11  # the body's own force pA of pass 1 (ABA), from which a refinement pass starts again
N_VEC = 12

MAT_S = 0  # motion subspace in body axes (6 x nu)
MAT_IA = 1  # articulated (ABA) or composite (CRBA) inertia, rigid block
MAT_U = 2  # U = IA S_free (ABA) / F = Ic S (CRBA)
MAT_DINV = 3  # (S^T IA S)^-1 over the free DOFs
MAT_IAP = 4  # IA - U D^-1 U^T; dM_rr/dt scratch of a flexible body
MAT_TMP = 5
N_MAT = 6


@_njit(cache=True)
def view(a, offset, rows, cols):
    """The (rows x cols) matrix stored row-major in ``a[offset:]``."""
    return a[offset:offset + rows * cols].reshape((rows, cols))
