"""The terms G1, F2, G2 of a flexible body's mass matrix summed over its nodes (numba): O(N_r n) per evaluation.

They come only from nodes whose own inertia turns with their elastic rotation (rotary inertia J_j about the
node, or a centre-of-mass offset p_j; TM-2020-5008164 eq. E.1.3 with the first-order attitude ``I + theta~``
of E.1.17). Per node j, with ``theta = lambda_j eta``, ``u = gamma_j eta`` and their rates, ``dP = (theta x p)~``,
the part of the body's kinetic energy they carry is (the blocks of ``Y_j' M_nd,j Y_j``, E.1.34, that the tables
G1, F2, G2 of :mod:`dynamics.flexible_body` hold)

    T_j = 1/2 theta_dot' dJ theta_dot + m theta_dot' dP u_dot + omega' Q theta_dot,
    dJ = (theta~ J - J theta~)  [G1]  - theta~ J theta~  [G2],      Q = -theta~ J theta~ - m u~ dP  [F2],

(the offset term of G1 with G1; order 1 keeps G1 only). The body's equations take from it (Lagrange for eta,
Euler-Poincare for the reference frame, as :func:`dynamics.flexible_kernels.modal_mass_and_bias` does for the
tables): the modal mass ``G0 + sum_j lambda_j' dJ lambda_j + m (lambda_j' dP gamma_j + gamma_j' dP' lambda_j)``,
the coupling ``M_re[omega rows] += Q lambda_j``, and the velocity terms

    b_m += lambda_j' (d/dt dpi_theta - dT/dtheta) + gamma_j' (d/dt dpi_u - dT/du),
    b_r[omega rows] += dQ/dt theta_dot + omega x (Q theta_dot),

with the per-node momenta ``pi_theta = dJ theta_dot + m dP u_dot + Q' omega``, ``pi_u = -m dP theta_dot``
differentiated at zero acceleration. Written out (cross products; G1: ``2 thd x (J thd)``, offsets
``m ((thd x p) x ud - p x (ud x thd))`` and ``m thd x (thd x p)``; G2: ``-2 thd x (J (th x thd))``; F2 below)
each evaluation costs three kinds of pass instead of contractions of n^3 and n^4 tables: the stacked shapes
times the modal coordinates and rates (``theta, u`` and their rates of every node: 2 x 3N x n), the 3-vector
algebra per node, and the products back (``lambda' a``, ``gamma' z`` and the 3 x n columns ``Q lambda``:
4 x 3N x n). The data are laid out node-minor (structure of arrays: the x components of all nodes, then the y,
...), so that the shape passes are loops over the 3N stacked entries that LLVM vectorizes; the per-node algebra
forms each node's ``dJ`` and ``Q`` once per evaluation, which every product with the modal mass (a refinement
pass) then reuses. Against the per-node records they replace (same data, one process, 2026-11-28): the terms with
their forces 0.63x (105 nodes, 20 modes) and 0.51x (101 nodes, 196 modes), a product with ``dG`` 0.19x and 0.26x.
The shape passes take four rows of the shapes per sweep over the 3N entries (:func:`shapes_times`,
``_shapes_dot``: a quarter of the loads and stores of the outputs), and the 3 x n columns with the dot back two
rows at a time against four vectors (:func:`columns_times`, which :mod:`dynamics.kernels.node_mass` shares).
Against one row at a time (2026-12-07, ``benchmarks/node_terms_passes.py``: the tube of
``benchmarks/flexible_scaling.py``, 101 nodes, 196 modes, and the hub beam of ``benchmarks/flexible_vs_exudyn.py``,
105 nodes, 20 modes; interleaved medians, load 0.9 on 2 cores): the shapes times eta and the rates 0.56x and 0.72x,
a product with the modal mass 0.78x and 0.82x, the terms with their forces 0.75x and 0.93x. The per-node algebra
runs in several loops over the nodes, each storing at most three node-minor streams and without branches (a term
left out is scaled by zero, offsets are zero without them): LLVM cannot prove numba's arrays disjoint (no
``noalias``) and vectorizes a loop only when it can check its stores against its loads at run time in a few
comparisons, which the one loop of ~40 streams (18 stored), or a branch per term, defeated (measured 2026-12-07 with
``inspect_asm``: 4 stored streams vectorize, 6 do not; a loop over ``range(N if flag else 0)`` is not vectorized,
``if flag:`` around ``range(N)`` is). So each row of ``dJ`` and of ``Q`` is a loop (``J theta~``'s rows again in
each), the forces another with ``Q thd`` recomputed rather than read back, ``Z`` one more with offsets: the hub
beam's terms 0.82x with forces and 0.77x without (main, interleaved, load 3).
The result equals the tables' to round-off (``tests/flexible/test_node_inertia.py``).

A refinement's late products (:func:`node_inertia_times_single`, for corrections below 1e-7 of the accelerations:
:mod:`dynamics.kernels.articulated_body`) sweep a single-precision copy of ``Lambda`` (and ``Gamma`` with CG
offsets) that :func:`node_params` appends: the sweeps of a product are bound by the cache's bandwidth (``Lambda`` of
the 196-mode tube, 475 KB, about this EPYC's 512 KB L2), and in float32 they move half the bytes and do eight
products per vector instruction: 0.46x of the double product there, 0.70x at 20 modes (2026-12-07). From
:data:`NODE_MAJOR_MODES` = 96 modes (:func:`node_major`) the copies are node-major (per node j its rows
``lambda_j`` and with offsets ``gamma_j``, n numbers each) and a product is one sweep instead of two: per node the
dot products of its rows with ``x`` (``alpha``), its ``a`` in double, and ``out += lambda_j' a`` while its rows
(4.7 KB at 196 modes in double) are in L1; the double product too (:func:`node_inertia_times`, two nodes at a time:
one load of ``x`` and of ``out`` per six rows), over a node-major double copy that :func:`node_params` then adds.
Measured 2026-12-07 against the two mode-major sweeps. The kernels alone, called in a loop on data that stay in
cache (``benchmarks/node_terms_passes.py``, interleaved medians, load 0.7-1.8 on 2 cores): on the 196-mode tube the
double product 0.90-0.95x and the single 0.88-0.99x; on random data of the tube's size the single 0.85-0.9x at 196
modes and 0.78-0.80x at 400 (the mode-major copy then exceeds the L2), about even at 128-150, 1.1x at 100, 1.2x at
50, 1.43-1.48x at the hub beam's 20 modes (the per-node reductions, three per node and product against one per
mode, cost more than the second read saves); the double 0.86x at 196, 0.78x at 400, 1.1-1.2x at 20. In the
forward dynamics, where other passes evict the shapes between products (``benchmarks/flexible_scaling.py
--deck-only``, runs of ``main`` and this code alternated, medians, load 1-3): the tube's order 2 at 196 modes
0.94x (167 against 178 us; 4.70-4.83x order 0 against 4.93-5.10x), order 1 0.94x (4.61-4.71x against 4.92-4.93x),
at 400 modes 0.94-0.95x and 0.91-0.96x, with the threshold at 96 modes order 2 0.97-0.98x at 100 modes and 0.96x
at 128 (order 1 0.98x and 0.95x). Below 96 modes the sweeps stay mode-major. The node-major double copy is the
price: ``3 N n`` (``6 N n`` with offsets) more doubles where :func:`node_major` (475 KB on the tube at 196 modes),
the float32 copy without offsets half of what it was.

Tried for the node terms' passes and dropped (2026-12-07, random data of the tube's size, 101 nodes, 196 modes,
interleaved medians, load 0.9-1.8): the same node-major fusion, one read of ``Lambda`` and ``Gamma`` per evaluation
instead of two (per node the 12 dot products of its 6 rows with eta and the rates, the algebra, then ``M_re``'s 3
rows and ``b_m`` from the same rows): 55 against 48 us for the passes alone, without the algebra (node-major
apart: forward 26 against 22, back 35 against 31); blocks of 8 to 51 nodes stored mode-major within the block
(forward and back of a block while it is in L2): 56-77 against 49-53 us; four nodes to a vector lane (one block of
4 nodes' 12 numbers per mode, no reductions per node): LLVM vectorized neither the loops nor their lanes (scalar
code, 26 against 15 us for a product); the ``Gamma`` back sweep using the zero diagonal of the skew
``m (u + d)~`` (6 instead of 8 multiply-adds per entry and row pair): 1.03x; six or eight rows of the shapes per
forward sweep instead of four: 1.0-1.05x (1.2x at 20 modes). At 196 modes the four mode-major sweeps of a shared
evaluation run near the machine's floor (~36 us of multiply-adds at two 4-wide per cycle, measured 48).
Fusing the two double sweeps by blocks of nodes over the mode-major layout (a block's ``alpha``, its ``a``, its
columns back while they are in cache) measured 2-4x slower (196 and 20 modes, 2026-12-07): a block's three
component ranges are short pieces of each mode's row, which LLVM vectorized over the modes with emulated gathers
rather than along the rows (numba has no ``noalias`` or loop pragmas).

Where the modal mass is formed rather than refined (:func:`node_inertia_modal_mass`: the factored modal mass of a
body with few modes, ``dynamics.system.refinement_budget``, and the composite-inertia mass matrix),
``Lambda' D Lambda`` (``D`` the block diagonal of the nodes' ``dJ``) is formed as a symmetric matrix product: per
block of four modes s the products ``dJ lambda_s`` as loops over the nodes that LLVM vectorizes, then the lower
triangle's dot products two rows of ``Lambda`` at a time against the four (a 2 x 4 register tile); 0.3-0.5x of the
dot products one at a time it replaces (2026-12-07, 105 nodes, 20 modes, loaded machine). The tile indexes the rows
of ``Lambda`` rather than taking a view of each (a view costs a reference count's increment and decrement): 0.76x
(20 modes) and 0.67x (196 modes) of the formation with views. The bias ``Lambda a`` and the ``Q lambda`` columns
share one sweep over ``Lambda`` the same way.

Data (:mod:`dynamics.layout`): ``FX_NODES`` points at what :func:`node_params` packs for ``FX_NODE_COUNT``
nodes (whether any node has a CG offset; the masses, offsets and inertias node-minor; the rotation shapes
``Lambda`` and translation shapes ``Gamma``, n x 3N each, row s holding mode s's components node-minor; where
:func:`node_major`, the shapes node-major in double; the shapes in single precision);
``FX_NODE_TERMS`` says which terms; ``FX_P_NODES`` holds ``NODE_STATE`` numbers per node: each node's
``theta`` and ``u`` for the products with the modal mass of the same evaluation (:func:`node_inertia_times`,
:func:`node_inertia_modal_mass`) and the per-node coefficients and scratch of the passes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.flexible_kernels import FAST_SUMS, dots6
from dynamics.layout import NODE_F2, NODE_G1, NODE_G2

# where each node's numbers sit in the body's FX_P_NODES block, in units of the node count N (node-minor):
S_THETA = 0  # theta = lambda eta (3 N)
S_U = 3  # u = gamma eta (3 N), zero without CG offsets
S_THETA_DOT = 6  # lambda e (3 N)
S_U_DOT = 9  # gamma e (3 N)
S_A = 12  # the coefficients of lambda' (3 N) ...
S_Z = 15  # ... and of gamma' (3 N) in b_m or a product with dG
S_W = 18  # Q (9 N, entry (a, b) at (3 a + b) N): M_re[omega rows] += sum_j Q_j lambda_j
S_D = 27  # dJ (9 N): the node terms of the modal mass, for its products and for forming it
NODE_STATE = 36
"""Pool numbers per node (:data:`dynamics.layout.FX_P_NODES`)."""


NODE_MAJOR_MODES = 96
"""From this many modes (and at most ``S_D - S_A`` = 15 per node: the pass scratch holds the single-precision
product's ``x - prev`` and sum in float32) :func:`node_params` adds node-major copies of the shapes, in double and
in single precision, and the products with the modal mass (:func:`node_inertia_times`,
:func:`node_inertia_times_single`) sweep them once; below, they sweep the mode-major ones twice (module
docstring)."""


@njit(cache=True, inline="always")
def node_major(count, n):
    """Whether the products with the modal mass of ``count`` nodes and ``n`` modes sweep node-major copies of the
    shapes (:data:`NODE_MAJOR_MODES`)."""
    return NODE_MAJOR_MODES <= n <= (S_D - S_A) * count


def node_params(mass, cg, inertia, shapes):
    """The node data as :mod:`dynamics.kernels.node_inertia` reads them from params: ``[any CG offset, m (N),
    p (3 N), J (9 N), Lambda (n x 3 N), Gamma (n x 3 N), the shapes node-major where :func:`node_major`, the
    shapes in single precision]``, node-minor (module docstring), from the masses (N), CG offsets (N, 3), inertias
    (N, 3, 3) and shapes ``[lambda; gamma]`` (N, 6, n). Node-major: per node j its rows ``lambda_j`` and, when any
    node has a CG offset, ``gamma_j`` (N x 3 x n or N x 6 x n). In single precision (float32, padded to a whole
    number of doubles): the same node-major where :func:`node_major`, else ``Lambda`` and, with a CG offset,
    ``Gamma`` mode-major (n x 3 N each, as the double ones)."""
    count, _, n = shapes.shape
    offset = bool(np.any(np.asarray(cg) != 0.0))
    rotations = np.transpose(shapes[:, :3, :], (2, 1, 0)).reshape(n, 3 * count)
    translations = np.transpose(shapes[:, 3:, :], (2, 1, 0)).reshape(n, 3 * count)
    major = shapes[:, :6 if offset else 3, :].ravel() if node_major(count, n) else np.zeros(0)
    if major.size:
        single = major
    else:
        single = np.concatenate([rotations.ravel(), translations.ravel() if offset else []])
    single = np.concatenate([single, np.zeros(single.size % 2)]).astype(np.float32)
    return np.concatenate([[float(offset)], mass, np.asarray(cg).T.ravel(),
                           np.asarray(inertia).reshape(count, 9).T.ravel(), rotations.ravel(), translations.ravel(),
                           major, single.view(np.float64)])


@njit(cache=True, inline="always")
def cross3(a0, a1, a2, b0, b1, b2):
    """``a x b`` of two 3-vectors given by their components."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, inline="always")
def add_scaled3(a0, a1, a2, s, x0, x1, x2):
    """``a + s x`` of two 3-vectors given by their components."""
    return a0 + s * x0, a1 + s * x1, a2 + s * x2


@njit(cache=True, inline="always")
def add_cross3(a0, a1, a2, s, b0, b1, b2, c0, c1, c2):
    """``a + s (b x c)`` of 3-vectors given by their components."""
    x0, x1, x2 = cross3(b0, b1, b2, c0, c1, c2)
    return a0 + s * x0, a1 + s * x1, a2 + s * x2


@njit(cache=True, inline="always")
def node_vector(x, N, j):
    """Node j's 3-vector of the node-minor ``x`` (component a at ``x[a N + j]``)."""
    return x[j], x[N + j], x[2 * N + j]


@njit(cache=True, inline="always")
def store_node_vector(x, N, j, v0, v1, v2):
    """Node j's 3-vector ``v`` into the node-minor ``x``."""
    x[j] = v0
    x[N + j] = v1
    x[2 * N + j] = v2


@njit(cache=True, inline="always")
def node_vectors(state, N):
    """The six slots of 3 N numbers (node-minor) that begin the scratch of both node kernels (this module's
    ``NODE_STATE`` and :data:`dynamics.kernels.node_mass.MASS_NODE_STATE` numbers per node): ``theta``, ``u``,
    their rates, and the coefficients of ``lambda'`` and of ``gamma'``."""
    return (node_slot(state, N, S_THETA, 3), node_slot(state, N, S_U, 3), node_slot(state, N, S_THETA_DOT, 3),
            node_slot(state, N, S_U_DOT, 3), node_slot(state, N, S_A, 3), node_slot(state, N, S_Z, 3))


@njit(cache=True, inline="always")
def node_slot(state, N, start, size):
    """The ``size`` N numbers of the scratch ``state`` of N nodes that start at ``start`` N (the ``S_*`` slots)."""
    return state[start * N:(start + size) * N]


@njit(cache=True, inline="always")
def node_inertia3(params, at, N, j):
    """Node j's inertia J (entry (a, b) at ``params[at + (3 a + b) N + j]``), row major."""
    return (params[at + j], params[at + N + j], params[at + 2 * N + j],
            params[at + 3 * N + j], params[at + 4 * N + j], params[at + 5 * N + j],
            params[at + 6 * N + j], params[at + 7 * N + j], params[at + 8 * N + j])


@njit(cache=True, inline="always")
def mat3_times(M, x0, x1, x2):
    """M x for the row-major 3 x 3 ``M``."""
    return (M[0] * x0 + M[1] * x1 + M[2] * x2, M[3] * x0 + M[4] * x1 + M[5] * x2,
            M[6] * x0 + M[7] * x1 + M[8] * x2)


@njit(cache=True, inline="always")
def _times_cross(M, t0, t1, t2):
    """``M t~`` (row major): its columns are ``M (t x e_b)``."""
    return (t2 * M[1] - t1 * M[2], t0 * M[2] - t2 * M[0], t1 * M[0] - t0 * M[1],
            t2 * M[4] - t1 * M[5], t0 * M[5] - t2 * M[3], t1 * M[3] - t0 * M[4],
            t2 * M[7] - t1 * M[8], t0 * M[8] - t2 * M[6], t1 * M[6] - t0 * M[7])


@njit(cache=True, inline="always")
def _node_matrix_times(D, N, j, x0, x1, x2):
    """``dJ_j x`` for node j's 3 x 3 ``dJ`` kept node-minor in ``D`` (entry (a, b) at ``D[(3 a + b) N + j]``)."""
    return (D[j] * x0 + D[N + j] * x1 + D[2 * N + j] * x2,
            D[3 * N + j] * x0 + D[4 * N + j] * x1 + D[5 * N + j] * x2,
            D[6 * N + j] * x0 + D[7 * N + j] * x1 + D[8 * N + j] * x2)


@njit(cache=True, inline="always")
def shapes_at(o, N, n):
    """params offsets of ``Lambda`` and ``Gamma`` in the :func:`node_params` of ``N`` nodes at ``o``."""
    _, _, _, lam, gam = _layout(o, N, n)
    return lam, gam


@njit(cache=True, inline="always")
def _layout(o, N, n):
    """params offsets of the masses, CG offsets, inertias, Lambda and Gamma (:func:`node_params`)."""
    m = o + 1
    lam = m + 13 * N
    return m, m + N, m + 4 * N, lam, lam + 3 * N * n


@njit(cache=True, fastmath=FAST_SUMS)
def shapes_times(params, at, n, width, x, y, out_x, out_y, with_y):
    """``out_x = S' x`` (and with ``with_y`` ``out_y = S' y``) for the n x ``width`` shapes S at ``params[at:]``:
    four rows of S per sweep over the outputs (a quarter of their loads and stores; 0.55-0.85x of one row at a
    time, 2026-12-07), LLVM vectorizing over the entries."""
    S = params[at:at + n * width].reshape((n, width))
    for r in range(width):
        out_x[r] = 0.0
        out_y[r] = 0.0
    s = 0
    while s + 4 <= n:
        x0, x1, x2, x3 = x[s], x[s + 1], x[s + 2], x[s + 3]
        if with_y:
            y0, y1, y2, y3 = y[s], y[s + 1], y[s + 2], y[s + 3]
            for r in range(width):
                a0, a1, a2, a3 = S[s, r], S[s + 1, r], S[s + 2, r], S[s + 3, r]
                out_x[r] += a0 * x0 + a1 * x1 + a2 * x2 + a3 * x3
                out_y[r] += a0 * y0 + a1 * y1 + a2 * y2 + a3 * y3
        else:
            for r in range(width):
                out_x[r] += S[s, r] * x0 + S[s + 1, r] * x1 + S[s + 2, r] * x2 + S[s + 3, r] * x3
        s += 4
    for s in range(s, n):
        xs = x[s]
        ys = y[s]
        for r in range(width):
            out_x[r] += S[s, r] * xs
            if with_y:
                out_y[r] += S[s, r] * ys


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _rows_dot(S, n, width, a, out, zero):
    """``out += S a`` for the n x ``width`` shapes ``S``, summed in the type of ``zero`` (0.0, or np.float32(0.0)
    for the float32 shapes of :func:`node_inertia_times_single`): the dot products of four rows at a time with ``a``
    (one load of ``a`` per four multiply-adds)."""
    s = 0
    while s + 4 <= n:
        c0 = c1 = c2 = c3 = zero
        for r in range(width):
            z = a[r]
            c0 += S[s, r] * z
            c1 += S[s + 1, r] * z
            c2 += S[s + 2, r] * z
            c3 += S[s + 3, r] * z
        out[s] += c0
        out[s + 1] += c1
        out[s + 2] += c2
        out[s + 3] += c3
        s += 4
    for s in range(s, n):
        acc = zero
        for r in range(width):
            acc += S[s, r] * a[r]
        out[s] += acc


@njit(cache=True, fastmath=FAST_SUMS)
def _shapes_dot(params, at, n, width, a, out):
    """``out += S a`` for the n x ``width`` shapes S at ``params[at:]`` (:func:`_rows_dot`)."""
    _rows_dot(params[at:at + n * width].reshape((n, width)), n, width, a, out, 0.0)


@njit(cache=True, fastmath=FAST_SUMS)
def columns_times(params, at, n, width, W, z, first, with_c, with_dot, Mre, bm):
    """For the n x ``width`` shapes S at ``params[at:]``: with ``with_c`` ``Mre[first + a, s] += sum_(b, j)
    W_j[a, b] S_j[b, s]`` (a < 3; ``W``: the nodes' 3 x 3 matrices node-minor, entry (a, b) of node j at
    ``W[(3 a + b) N + j]``), with ``with_dot`` ``bm += S z``: both in one sweep over S, two rows at a time against
    the four vectors (:func:`_tile_dots`; 0.87x of one row at a time at 196 modes, 2026-12-07)."""
    if not with_c:
        if with_dot:
            _shapes_dot(params, at, n, width, z, bm)
        return
    S = params[at:at + n * width].reshape((n, width))
    W0, W1, W2 = W[:width], W[width:2 * width], W[2 * width:3 * width]
    if not with_dot:  # one row at a time (a 2 x 3 tile measured no faster, 2026-12-07)
        for s in range(n):
            r0 = r1 = r2 = 0.0
            for r in range(width):
                x = S[s, r]
                r0 += W0[r] * x
                r1 += W1[r] * x
                r2 += W2[r] * x
            Mre[first, s] += r0
            Mre[first + 1, s] += r1
            Mre[first + 2, s] += r2
        return
    for s in range(0, n, 2):
        two = s + 1 < n
        a0, a1, a2, a3, b0, b1, b2, b3 = _tile_dots(S, s, s + 1 if two else s, W0, W1, W2, z, 4, two)
        Mre[first, s] += a0
        Mre[first + 1, s] += a1
        Mre[first + 2, s] += a2
        bm[s] += a3
        if two:
            Mre[first, s + 1] += b0
            Mre[first + 1, s + 1] += b1
            Mre[first + 2, s + 1] += b2
            bm[s + 1] += b3


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_terms(params, o, count, n, terms, eta, V, e, with_bias, Mre, br, bm, state):
    """Add the node terms (module docstring) to ``Mre`` (6 x n: the omega rows, F2), and with ``with_bias`` to
    ``br`` (6) and ``bm`` (n); keep every node's ``theta`` and ``u`` in ``state`` (``NODE_STATE`` per node).
    ``o``: params offset of the :func:`node_params` of ``count`` nodes; ``terms``: NODE_* bits; ``V``, ``e``:
    body velocity and modal rates."""
    node_inertia_pass(params, o, count, n, terms, eta, V, e, with_bias, br, state, False)
    N = count
    width = 3 * N
    _, _, _, lam, gam = _layout(o, N, n)
    # b_m += Lambda A and the omega rows of M_re += the Q lambda columns, in one sweep over Lambda
    columns_times(params, lam, n, width, node_slot(state, N, S_W, 9), node_slot(state, N, S_A, 3), 0,
                  (terms & NODE_F2) != 0, with_bias, Mre, bm)
    if with_bias and params[o] != 0.0:
        _shapes_dot(params, gam, n, width, node_slot(state, N, S_Z, 3), bm)


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_pass(params, o, count, n, terms, eta, V, e, with_bias, br, state, with_u):
    """:func:`node_inertia_terms` but for its products back: the shapes times eta and the rates (``theta``,
    ``u`` and their rates into ``state``; ``u`` zero without CG offsets unless ``with_u``), each node's ``dJ``
    (``S_D``), ``Q`` (``S_W``, with F2) and, with ``with_bias``, the coefficients of ``lambda'`` and ``gamma'``
    in ``b_m`` (``S_A``, ``S_Z``) and the node terms of ``b_r`` added to ``br``. Left for the caller: ``M_re[omega
    rows] += sum_j Q_j lambda_j``, ``b_m += Lambda A + Gamma Z`` (:func:`columns_times`), which
    :func:`dynamics.kernels.node_mass.node_mass_terms` folds into its own sweeps over the same shapes."""
    g1 = (terms & NODE_G1) != 0
    g2 = (terms & NODE_G2) != 0
    f2 = (terms & NODE_F2) != 0
    N = count
    width = 3 * N
    offset = params[o] != 0.0
    ma, pa, jb, lam, gam = _layout(o, N, n)
    th, uu, thd, ud, A, Z = node_vectors(state, N)
    W = node_slot(state, N, S_W, 9)
    D = node_slot(state, N, S_D, 9)
    shapes_times(params, lam, n, width, eta, e, th, thd, with_bias)
    if offset or with_u:
        shapes_times(params, gam, n, width, eta, e, uu, ud, with_bias)
    else:
        for r in range(width):
            uu[r] = 0.0
            ud[r] = 0.0
    w0, w1, w2 = V[0], V[1], V[2]
    br0 = br1 = br2 = 0.0
    # the node's matrices of this evaluation, row a of each per loop over the nodes (three streams stored: LLVM
    # vectorizes it, see the forces below): dJ = theta~ J - J theta~ [G1] - theta~ J theta~ [G2], kept for the
    # products with the modal mass, and Q = -theta~ J theta~ - m u~ dP [F2]. With J_k the rows of J, row a of
    # J theta~ is J_a x theta, of theta~ J t[a+1] J_(a+2) - t[a+2] J_(a+1), of theta~ J theta~ the same with the rows
    # of J theta~ (indices mod 3); -m u~ dP = -m ((theta x p) u' - (u . (theta x p)) 1).
    k1 = 1.0 if g1 else 0.0
    k2 = 1.0 if g2 else 0.0
    for a in range(3):
        a1 = (a + 1) % 3
        a2 = (a + 2) % 3
        Ja = params[jb + 3 * a * N:jb + 3 * (a + 1) * N]  # row a of every node's J, node-minor
        J1 = params[jb + 3 * a1 * N:jb + 3 * (a1 + 1) * N]
        J2 = params[jb + 3 * a2 * N:jb + 3 * (a2 + 1) * N]
        Da = D[3 * a * N:3 * (a + 1) * N]
        Wa = W[3 * a * N:3 * (a + 1) * N]
        if g1 or g2:
            for j in range(N):
                t0, t1, t2 = node_vector(th, N, j)
                ta1, ta2 = th[a1 * N + j], th[a2 * N + j]
                x0, x1, x2 = node_vector(J1, N, j)
                y0, y1, y2 = node_vector(J2, N, j)
                r0, r1, r2 = node_vector(Ja, N, j)
                s0, s1, s2 = cross3(x0, x1, x2, t0, t1, t2)  # row a + 1 of J theta~
                q0, q1, q2 = cross3(y0, y1, y2, t0, t1, t2)  # row a + 2
                P0, P1, P2 = cross3(r0, r1, r2, t0, t1, t2)  # row a
                # dJ row a: k1 (t[a+1] J_(a+2) - t[a+2] J_(a+1) - P_a) - k2 (t[a+1] P_(a+2) - t[a+2] P_(a+1))
                store_node_vector(Da, N, j,
                                  k1 * (ta1 * y0 - ta2 * x0 - P0) - k2 * (ta1 * q0 - ta2 * s0),
                                  k1 * (ta1 * y1 - ta2 * x1 - P1) - k2 * (ta1 * q1 - ta2 * s1),
                                  k1 * (ta1 * y2 - ta2 * x2 - P2) - k2 * (ta1 * q2 - ta2 * s2))
        if f2:
            for j in range(N):
                m = params[ma + j]
                p0, p1, p2 = params[pa + j], params[pa + N + j], params[pa + 2 * N + j]
                t0, t1, t2 = node_vector(th, N, j)
                u0, u1, u2 = node_vector(uu, N, j)
                ta1, ta2 = th[a1 * N + j], th[a2 * N + j]
                x0, x1, x2 = node_vector(J1, N, j)
                y0, y1, y2 = node_vector(J2, N, j)
                s0, s1, s2 = cross3(x0, x1, x2, t0, t1, t2)
                q0, q1, q2 = cross3(y0, y1, y2, t0, t1, t2)
                c0, c1, c2 = cross3(t0, t1, t2, p0, p1, p2)  # theta x p (zero without an offset)
                ca = c0 if a == 0 else (c1 if a == 1 else c2)
                uc = u0 * c0 + u1 * c1 + u2 * c2
                store_node_vector(Wa, N, j,
                                  -(ta1 * q0 - ta2 * s0) - m * (ca * u0 - (uc if a == 0 else 0.0)),
                                  -(ta1 * q1 - ta2 * s1) - m * (ca * u1 - (uc if a == 1 else 0.0)),
                                  -(ta1 * q2 - ta2 * s2) - m * (ca * u2 - (uc if a == 2 else 0.0)))
    if not with_bias:
        return
    # the forces in loops of their own, without branches (each term scaled by its 0/1 flag, the offset terms zero
    # without offsets) and with at most three streams stored each: with more stores (the matrices' 18, or A and Z
    # together) or a branch per term, LLVM vectorizes no loop (it checks the stores against the loads at run time
    # only up to a few pairs and does not unswitch that many conditions). J theta~ and Q thd again.
    kf = 1.0 if f2 else 0.0
    for j in range(N):
        m = params[ma + j]
        p0, p1, p2 = params[pa + j], params[pa + N + j], params[pa + 2 * N + j]
        t0, t1, t2 = node_vector(th, N, j)
        u0, u1, u2 = node_vector(uu, N, j)
        d0, d1, d2 = node_vector(thd, N, j)
        v0, v1, v2 = node_vector(ud, N, j)
        c0, c1, c2 = cross3(t0, t1, t2, p0, p1, p2)  # theta x p
        h0, h1, h2 = cross3(d0, d1, d2, p0, p1, p2)  # thd x p
        J = node_inertia3(params, jb, N, j)
        P = _times_cross(J, t0, t1, t2)
        # coefficients of lambda' and gamma' in b_m; G1: 2 thd x (J thd), offsets m ((thd x p) x ud - p x (ud x
        # thd)) and m thd x (thd x p)
        j0, j1, j2 = mat3_times(J, d0, d1, d2)
        x0, x1, x2 = cross3(d0, d1, d2, j0, j1, j2)
        a0, a1, a2 = 2.0 * k1 * x0, 2.0 * k1 * x1, 2.0 * k1 * x2
        x0, x1, x2 = cross3(h0, h1, h2, v0, v1, v2)
        y0, y1, y2 = cross3(v0, v1, v2, d0, d1, d2)
        yy0, yy1, yy2 = cross3(p0, p1, p2, y0, y1, y2)
        mk = m * k1
        a0 += mk * (x0 - yy0)
        a1 += mk * (x1 - yy1)
        a2 += mk * (x2 - yy2)
        # G2: -2 thd x J (theta x thd)
        jw0, jw1, jw2 = mat3_times(P, d0, d1, d2)  # J (theta x thd)
        x0, x1, x2 = cross3(d0, d1, d2, jw0, jw1, jw2)  # thd x J (theta x thd)
        a0, a1, a2 = add_scaled3(a0, a1, a2, -2.0 * k2, x0, x1, x2)
        # F2: b_r += dQ/dt thd + omega x (Q thd), Q thd = -theta x (J (theta x thd)) - m u x ((theta x p) x thd)
        x0, x1, x2 = cross3(t0, t1, t2, jw0, jw1, jw2)
        y0, y1, y2 = cross3(c0, c1, c2, d0, d1, d2)
        q0, q1, q2 = cross3(u0, u1, u2, y0, y1, y2)
        r0, r1, r2 = cross3(w0, w1, w2, -x0 - m * q0, -x1 - m * q1, -x2 - m * q2)
        x0, x1, x2 = cross3(d0, d1, d2, jw0, jw1, jw2)  # thd x J (theta x thd) again
        g0, g1_, g2_ = r0 - x0, r1 - x1, r2 - x2
        # b_m (lambda'): dQ/dt' omega - dT/dtheta
        ja0, ja1, ja2 = mat3_times(P, w0, w1, w2)  # J (theta x omega)
        y0, y1, y2 = cross3(d0, d1, d2, w0, w1, w2)  # thd x omega
        jc0, jc1, jc2 = mat3_times(J, y0, y1, y2)
        x0, x1, x2 = cross3(d0, d1, d2, ja0, ja1, ja2)
        y0, y1, y2 = cross3(t0, t1, t2, jc0, jc1, jc2)
        s0, s1, s2 = cross3(w0, w1, w2, jw0, jw1, jw2)
        b0, b1, b2 = -(2.0 * x0 + y0 + s0), -(2.0 * x1 + y1 + s1), -(2.0 * x2 + y2 + s2)
        # offsets, b_r: - m [ud x ((theta x p) x thd) + u x ((thd x p) x thd)]
        x0, x1, x2 = cross3(c0, c1, c2, d0, d1, d2)
        y0, y1, y2 = cross3(v0, v1, v2, x0, x1, x2)
        s0, s1, s2 = cross3(h0, h1, h2, d0, d1, d2)
        r0, r1, r2 = cross3(u0, u1, u2, s0, s1, s2)
        g0 -= m * (y0 + r0)
        g1_ -= m * (y1 + r1)
        g2_ -= m * (y2 + r2)
        # lambda': - m [(thd x p) x (u x omega) + (theta x p) x (ud x omega)] + m p x (thd x (omega x u))
        x0, x1, x2 = cross3(u0, u1, u2, w0, w1, w2)
        y0, y1, y2 = cross3(h0, h1, h2, x0, x1, x2)
        x0, x1, x2 = cross3(v0, v1, v2, w0, w1, w2)
        s0, s1, s2 = cross3(c0, c1, c2, x0, x1, x2)
        x0, x1, x2 = cross3(w0, w1, w2, u0, u1, u2)
        r0, r1, r2 = cross3(d0, d1, d2, x0, x1, x2)
        x0, x1, x2 = cross3(p0, p1, p2, r0, r1, r2)
        b0 += m * (x0 - y0 - s0)
        b1 += m * (x1 - y1 - s1)
        b2 += m * (x2 - y2 - s2)
        br0 += kf * g0
        br1 += kf * g1_
        br2 += kf * g2_
        store_node_vector(A, N, j, a0 + kf * b0, a1 + kf * b1, a2 + kf * b2)
    if not offset:
        for r in range(width):
            Z[r] = 0.0
    if offset:
        for j in range(N):
            # gamma': G1 m thd x (thd x p), F2 - m omega x ((theta x p) x thd)
            m = params[ma + j]
            p0, p1, p2 = params[pa + j], params[pa + N + j], params[pa + 2 * N + j]
            t0, t1, t2 = node_vector(th, N, j)
            d0, d1, d2 = node_vector(thd, N, j)
            c0, c1, c2 = cross3(t0, t1, t2, p0, p1, p2)
            h0, h1, h2 = cross3(d0, d1, d2, p0, p1, p2)
            x0, x1, x2 = cross3(d0, d1, d2, h0, h1, h2)
            z0, z1, z2 = m * k1 * x0, m * k1 * x1, m * k1 * x2
            x0, x1, x2 = cross3(c0, c1, c2, d0, d1, d2)
            y0, y1, y2 = cross3(w0, w1, w2, x0, x1, x2)
            store_node_vector(Z, N, j, z0 - m * kf * y0, z1 - m * kf * y1, z2 - m * kf * y2)
    br[0] += br0
    br[1] += br1
    br[2] += br2


@njit(cache=True, inline="always")
def _modal_mass_data(params, o, count, n, terms, state):
    """What the node terms of the modal mass are made of: whether there are any (G1 or G2), whether CG offsets
    enter them (G1), the params offsets of the masses, offsets, Lambda and Gamma, and each node's ``theta`` and
    ``dJ`` of this evaluation."""
    g1 = (terms & NODE_G1) != 0
    N = count
    ma, pa, _, lam, gam = _layout(o, N, n)
    return (g1 or (terms & NODE_G2) != 0, g1 and params[o] != 0.0, ma, pa, lam, gam,
            node_slot(state, N, S_THETA, 3), node_slot(state, N, S_D, 9))


@njit(cache=True, inline="always")
def _node_products(params, ma, pa, N, offset, th, D, A, Z):
    """Per node, from ``alpha = lambda x`` in ``A`` and ``beta = gamma x`` in ``Z``: ``a = dJ alpha + m (theta x p) x
    beta`` into ``A`` and ``z = m alpha x (theta x p)`` into ``Z`` (in double precision whatever ``A`` and ``Z``
    hold)."""
    for j in range(N):
        al0, al1, al2 = node_vector(A, N, j)
        a0, a1, a2 = _node_matrix_times(D, N, j, al0, al1, al2)
        if offset:
            m = params[ma + j]
            t0, t1, t2 = node_vector(th, N, j)
            c0, c1, c2 = cross3(t0, t1, t2, params[pa + j], params[pa + N + j], params[pa + 2 * N + j])
            b0, b1, b2 = node_vector(Z, N, j)
            x0, x1, x2 = cross3(c0, c1, c2, b0, b1, b2)
            a0, a1, a2 = add_scaled3(a0, a1, a2, m, x0, x1, x2)
            z0, z1, z2 = cross3(al0, al1, al2, c0, c1, c2)
            store_node_vector(Z, N, j, m * z0, m * z1, m * z2)
        store_node_vector(A, N, j, a0, a1, a2)


@njit(cache=True, fastmath=FAST_SUMS)
def _node_major_times(params, o, N, n, offset, ma, pa, th, D, x, out):
    """:func:`node_inertia_times` over the node-major double shapes in one sweep: per node ``alpha = lambda_j x``
    (and ``beta = gamma_j x``) as dot products of its rows, its ``a``, ``z`` (:func:`_node_coefficients`), and ``out
    += lambda_j' a + gamma_j' z`` while its rows are in L1; two nodes at a time without CG offsets (one load of
    ``x`` and of ``out`` per six rows)."""
    S, _ = _node_major_shapes(params, o, N, n)
    if offset:
        for j in range(N):
            r0, r1, r2, g0, g1, g2 = S[j, 0], S[j, 1], S[j, 2], S[j, 3], S[j, 4], S[j, 5]
            t0, t1, t2, u0, u1, u2 = dots6(r0, r1, r2, g0, g1, g2, x, n)
            a0, a1, a2, z0, z1, z2 = _node_coefficients(params, ma, pa, N, j, True, th, D, t0, t1, t2, u0, u1, u2)
            for k in range(n):
                out[k] += a0 * r0[k] + a1 * r1[k] + a2 * r2[k] + z0 * g0[k] + z1 * g1[k] + z2 * g2[k]
        return
    j = 0
    while j + 2 <= N:
        r0, r1, r2, q0, q1, q2 = S[j, 0], S[j, 1], S[j, 2], S[j + 1, 0], S[j + 1, 1], S[j + 1, 2]
        t0, t1, t2, u0, u1, u2 = dots6(r0, r1, r2, q0, q1, q2, x, n)
        a0, a1, a2 = _node_matrix_times(D, N, j, t0, t1, t2)
        b0, b1, b2 = _node_matrix_times(D, N, j + 1, u0, u1, u2)
        for k in range(n):
            out[k] += a0 * r0[k] + a1 * r1[k] + a2 * r2[k] + b0 * q0[k] + b1 * q1[k] + b2 * q2[k]
        j += 2
    if j < N:
        r0, r1, r2 = S[j, 0], S[j, 1], S[j, 2]
        t0 = t1 = t2 = 0.0
        for k in range(n):
            d = x[k]
            t0 += r0[k] * d
            t1 += r1[k] * d
            t2 += r2[k] * d
        a0, a1, a2 = _node_matrix_times(D, N, j, t0, t1, t2)
        for k in range(n):
            out[k] += a0 * r0[k] + a1 * r1[k] + a2 * r2[k]


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_times(params, o, count, n, terms, state, x, out):
    """``out += (G(eta) - G0 - tabled terms) x``: the node terms of the modal mass times ``x`` (n), with the
    ``theta`` and ``u`` that :func:`node_inertia_terms` kept in ``state``. O(count n)."""
    varies, offset, ma, pa, lam, gam, th, D = _modal_mass_data(params, o, count, n, terms, state)
    if not varies:
        return
    N = count
    width = 3 * N
    if node_major(N, n):
        _node_major_times(params, o, N, n, offset, ma, pa, th, D, x, out)
        return
    A, Z = node_vectors(state, N)[4:]
    shapes_times(params, lam, n, width, x, x, A, A, False)  # alpha = lambda x
    if offset:
        shapes_times(params, gam, n, width, x, x, Z, Z, False)  # beta = gamma x
    _node_products(params, ma, pa, N, offset, th, D, A, Z)
    _shapes_dot(params, lam, n, width, A, out)
    if offset:
        _shapes_dot(params, gam, n, width, Z, out)


@njit(cache=True, fastmath=FAST_SUMS)
def _single_shapes_times(S, n, width, x, prev, out):
    """``out = S' (x - prev)`` summed in single precision, for the n x ``width`` float32 shapes ``S`` (four rows of
    S per sweep over the outputs, as :func:`shapes_times`)."""
    for r in range(width):
        out[r] = 0.0
    s = 0
    while s + 4 <= n:
        x0, x1 = np.float32(x[s] - prev[s]), np.float32(x[s + 1] - prev[s + 1])
        x2, x3 = np.float32(x[s + 2] - prev[s + 2]), np.float32(x[s + 3] - prev[s + 3])
        for r in range(width):
            out[r] += S[s, r] * x0 + S[s + 1, r] * x1 + S[s + 2, r] * x2 + S[s + 3, r] * x3
        s += 4
    for s in range(s, n):
        xs = np.float32(x[s] - prev[s])
        for r in range(width):
            out[r] += S[s, r] * xs


@njit(cache=True, fastmath=FAST_SUMS)
def _single_shapes_dot(S, n, width, a, out):
    """``out += S a`` (``out`` double) summed in single precision, for the n x ``width`` float32 shapes ``S`` and
    float32 ``a`` (:func:`_rows_dot`)."""
    _rows_dot(S, n, width, a, out, np.float32(0.0))


@njit(cache=True, inline="always")
def _node_major_shapes(params, o, N, n):
    """The node-major double-precision shapes of :func:`node_params` (N x rows x n: per node its rows ``lambda_j``
    and, with CG offsets (rows = 6), ``gamma_j``; present where :func:`node_major`) and ``rows``."""
    rows = 6 if params[o] != 0.0 else 3
    start = _layout(o, N, n)[4] + 3 * N * n
    return params[start:start + rows * N * n].reshape((N, rows, n)), rows


@njit(cache=True, inline="always")
def _single_shapes(params, o, N, n):
    """The float32 numbers of the single-precision shapes of :func:`node_params` (``rows`` = 6 with CG offsets, else
    3, times N n) and ``rows``."""
    rows = 6 if params[o] != 0.0 else 3
    size = rows * N * n
    start = _layout(o, N, n)[4] + 3 * N * n + (size if node_major(N, n) else 0)
    return params[start:start + (size + 1) // 2].view(np.float32)[:size], rows


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _node_coefficients(params, ma, pa, N, j, offset, th, D, al0, al1, al2, be0, be1, be2):
    """Node j's ``a = dJ alpha + m (theta x p) x beta`` and ``z = m alpha x (theta x p)`` (:func:`_node_products`
    for one node, from ``alpha = lambda_j x``, ``beta = gamma_j x``), in double precision."""
    a0, a1, a2 = _node_matrix_times(D, N, j, al0, al1, al2)
    z0 = z1 = z2 = 0.0
    if offset:
        m = params[ma + j]
        t0, t1, t2 = node_vector(th, N, j)
        c0, c1, c2 = cross3(t0, t1, t2, params[pa + j], params[pa + N + j], params[pa + 2 * N + j])
        x0, x1, x2 = cross3(c0, c1, c2, be0, be1, be2)
        a0, a1, a2 = add_scaled3(a0, a1, a2, m, x0, x1, x2)
        z0, z1, z2 = cross3(al0, al1, al2, c0, c1, c2)
        z0, z1, z2 = m * z0, m * z1, m * z2
    return a0, a1, a2, z0, z1, z2


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _single_node_coefficients(params, ma, pa, N, j, offset, th, D, al0, al1, al2, be0, be1, be2):
    """:func:`_node_coefficients` rounded to float32 for the single-precision products back."""
    a0, a1, a2, z0, z1, z2 = _node_coefficients(params, ma, pa, N, j, offset, th, D, al0, al1, al2, be0, be1, be2)
    return (np.float32(a0), np.float32(a1), np.float32(a2), np.float32(z0), np.float32(z1), np.float32(z2))


@njit(cache=True, fastmath=FAST_SUMS)
def _node_major_times_single(S, params, N, n, offset, ma, pa, th, D, state, x, prev, out):
    """:func:`node_inertia_times_single` over the node-major float32 shapes ``S`` (N x rows x n) in one sweep: per
    node ``alpha = lambda_j (x - prev)`` (and ``beta = gamma_j (x - prev)``) as dot products of its rows, its ``a``,
    ``z`` in double, and ``acc += lambda_j' a + gamma_j' z`` while its rows are in L1; ``x - prev`` and ``acc`` in
    float32 in the pass scratch (``S_A`` to ``S_D``: 30 N float32, :func:`node_major` allows n <= 15 N)."""
    scratch = state[S_A * N:S_D * N].view(np.float32)
    dx = scratch[:n]
    acc = scratch[n:2 * n]
    zero = np.float32(0.0)
    for k in range(n):
        dx[k] = np.float32(x[k] - prev[k])
        acc[k] = zero
    if offset:
        for j in range(N):
            r0, r1, r2, g0, g1, g2 = S[j, 0], S[j, 1], S[j, 2], S[j, 3], S[j, 4], S[j, 5]
            t0, t1, t2, u0, u1, u2 = dots6(r0, r1, r2, g0, g1, g2, dx, n, zero)
            a0, a1, a2, z0, z1, z2 = _single_node_coefficients(params, ma, pa, N, j, True, th, D, t0, t1, t2, u0, u1,
                                                               u2)
            for k in range(n):
                acc[k] += a0 * r0[k] + a1 * r1[k] + a2 * r2[k] + z0 * g0[k] + z1 * g1[k] + z2 * g2[k]
    else:
        for j in range(N):
            r0, r1, r2 = S[j, 0], S[j, 1], S[j, 2]
            t0 = t1 = t2 = zero
            for k in range(n):
                d = dx[k]
                t0 += r0[k] * d
                t1 += r1[k] * d
                t2 += r2[k] * d
            a0, a1, a2, _, _, _ = _single_node_coefficients(params, ma, pa, N, j, False, th, D, t0, t1, t2, zero,
                                                            zero, zero)
            for k in range(n):
                acc[k] += a0 * r0[k] + a1 * r1[k] + a2 * r2[k]
    for k in range(n):
        out[k] += acc[k]


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_times_single(params, o, count, n, terms, state, x, prev, out):
    """``out += (G(eta) - G0 - tabled terms) (x - prev)`` as :func:`node_inertia_times` does for ``x``, over the
    float32 copy of the shapes (:func:`node_params`), the per-node algebra in double. Mode-major (fewer than
    :data:`NODE_MAJOR_MODES` modes): its two sweeps as :func:`node_inertia_times`'s, summed in float32 (half the
    bytes of sweeps that the cache's bandwidth bounds, and eight products per vector instruction instead of four).
    Node-major: one sweep, per node j ``alpha = lambda_j (x - prev)`` (and ``beta = gamma_j (x - prev)`` with CG
    offsets) as dot products of its rows, its ``a``, ``z`` (:func:`_node_products`'s algebra), and ``acc +=
    lambda_j' a + gamma_j' z`` while the node's rows are in L1, ``x - prev`` and ``acc`` kept in float32 in the pass
    scratch (module docstring). Error about 1e-8 of the summands' size ``|Lambda|' |dJ| |Lambda| |x - prev|``
    (float32's 6e-8 over sums of the modes and the nodes; ``tests/flexible/test_node_inertia.py``), which where the
    sum cancels is a larger part of the product itself (4e-4 on the late corrections of the 196-mode tube): for the
    refinement's late corrections only, where ``x - prev`` is a small fraction of ``x``
    (:mod:`dynamics.kernels.articulated_body`)."""
    varies, offset, ma, pa, lam, gam, th, D = _modal_mass_data(params, o, count, n, terms, state)
    if not varies:
        return
    N = count
    width = 3 * N
    single, rows = _single_shapes(params, o, N, n)
    if not node_major(N, n):
        A = node_slot(state, N, S_A, 3).view(np.float32)[:width]
        Z = node_slot(state, N, S_Z, 3).view(np.float32)[:width]
        L32 = single[:n * width].reshape((n, width))
        _single_shapes_times(L32, n, width, x, prev, A)
        if offset:
            G32 = single[n * width:].reshape((n, width))
            _single_shapes_times(G32, n, width, x, prev, Z)
        _node_products(params, ma, pa, N, offset, th, D, A, Z)
        _single_shapes_dot(L32, n, width, A, out)
        if offset:
            _single_shapes_dot(G32, n, width, Z, out)
        return
    _node_major_times_single(single.reshape((N, rows, n)), params, N, n, offset, ma, pa, th, D, state, x, prev, out)


TILE = 4
"""Modes per block of the modal mass's formation (:func:`node_inertia_modal_mass`): ``TILE`` products
``dJ lambda_s`` kept in the pass scratch at a time (``S_A`` to ``S_W + 9``: 15 N numbers, so at most 5)."""


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _tile_dots(S, r0, r1, y0, y1, y2, y3, count, two):
    """The dot products of row ``r0`` of ``S`` (and with ``two`` row ``r1``) with the first ``count`` (1..4) of
    ``y0 .. y3``: with four, the 2 x 4 sums of one sweep over the entries, which LLVM keeps in vector registers (a
    register tile as in a GEMM kernel: six loads per eight multiply-adds). The rows are indexed in ``S``, not taken
    as views: a view per call costs a reference count's increment and decrement (0.75x of the formation at 20
    modes, 2026-12-07)."""
    a0 = a1 = a2 = a3 = b0 = b1 = b2 = b3 = 0.0
    if count == 4 and two:
        for k in range(S.shape[1]):
            x = S[r0, k]
            z = S[r1, k]
            a0 += x * y0[k]
            a1 += x * y1[k]
            a2 += x * y2[k]
            a3 += x * y3[k]
            b0 += z * y0[k]
            b1 += z * y1[k]
            b2 += z * y2[k]
            b3 += z * y3[k]
        return a0, a1, a2, a3, b0, b1, b2, b3
    for k in range(S.shape[1]):
        x = S[r0, k]
        a0 += x * y0[k]
        a1 += x * y1[k]
        a2 += x * y2[k]
        a3 += x * y3[k]
    if two:
        for k in range(S.shape[1]):
            z = S[r1, k]
            b0 += z * y0[k]
            b1 += z * y1[k]
            b2 += z * y2[k]
            b3 += z * y3[k]
    return a0, a1, a2, a3, b0, b1, b2, b3


@njit(cache=True, inline="always")
def _tile_store(G, r, s0, count, a0, a1, a2, a3):
    """``G[r, s0 + t] += a_t`` and, off the diagonal, ``G[s0 + t, r] += a_t`` (t < count; only ``r <= s``)."""
    for t in range(count):
        s = s0 + t
        if r > s:
            continue
        v = a0 if t == 0 else (a1 if t == 1 else (a2 if t == 2 else a3))
        G[r, s] += v
        if r != s:
            G[s, r] += v


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_modal_mass(params, o, count, n, terms, state, G):
    """``G += sum_j lambda_j' dJ_j lambda_j + m_j (lambda_j' dP_j gamma_j + gamma_j' dP_j' lambda_j)`` (n x n):
    the node terms of the modal mass formed, O(count n^2) (for the composite-inertia mass matrix and a
    factored modal mass). ``Lambda' D Lambda`` (``D`` = blockdiag of the nodes' ``dJ``) is formed like a
    symmetric matrix product: per block of ``TILE`` modes s the products ``D lambda_s``, then the dot products
    of every row ``lambda_r``, ``r <= s``, with them two rows at a time (:func:`_tile_dots`): the lower
    triangle only, ~1.5 N n^2 multiply-adds. On the hub beam of ``benchmarks/flexible_vs_exudyn.py`` (105 nodes,
    20 modes: 6.7-7.2 us, ``benchmarks/derivative_profile.py``) the products ``dJ lambda_s`` take 2.4-2.9 us and
    the dot products (75.6k multiply-adds: the 2 x 4 tile keeps the FMA units about half busy) the rest. Tried and
    dropped (2026-12-07, same data, interleaved): a 3 x 4 tile (twelve sums: more than AVX2's sixteen registers
    hold with the loads) 1.75x the time; the products ``dJ lambda_s`` one component per loop 1.2x."""
    varies, offset, ma, pa, lam, gam, th, D = _modal_mass_data(params, o, count, n, terms, state)
    if not varies:
        return
    N = count
    width = 3 * N
    # views with the node index last, indexed by loop counters: LLVM vectorizes the products over the nodes
    L3 = params[lam:lam + n * width].reshape((n, 3, N))
    L2 = params[lam:lam + n * width].reshape((n, width))
    D3 = D.reshape((3, 3, N))
    Y = node_slot(state, N, S_A, 3 * TILE)
    Y3 = Y.reshape((TILE, 3, N))
    Y2 = Y.reshape((TILE, width))
    for s0 in range(0, n, TILE):
        ns = min(TILE, n - s0)
        for t in range(ns):
            # Y_t = dJ lambda[:, s], its three components in one loop over the nodes (lambda_s and dJ read once:
            # 0.77x of a loop per component, 2026-12-07, 105 nodes, 20 modes)
            s = s0 + t
            l0, l1, l2 = L3[s, 0], L3[s, 1], L3[s, 2]
            y0, y1, y2 = Y3[t, 0], Y3[t, 1], Y3[t, 2]
            for j in range(N):
                x0, x1, x2 = l0[j], l1[j], l2[j]
                y0[j] = D3[0, 0, j] * x0 + D3[0, 1, j] * x1 + D3[0, 2, j] * x2
                y1[j] = D3[1, 0, j] * x0 + D3[1, 1, j] * x1 + D3[1, 2, j] * x2
                y2[j] = D3[2, 0, j] * x0 + D3[2, 1, j] * x1 + D3[2, 2, j] * x2
        rows = s0 + ns
        y0, y1, y2, y3 = Y2[0], Y2[min(1, ns - 1)], Y2[min(2, ns - 1)], Y2[min(3, ns - 1)]
        for r in range(0, rows, 2):
            two = r + 1 < rows
            a0, a1, a2, a3, b0, b1, b2, b3 = _tile_dots(L2, r, r + 1 if two else r, y0, y1, y2, y3, ns, two)
            _tile_store(G, r, s0, ns, a0, a1, a2, a3)
            if two:
                _tile_store(G, r + 1, s0, ns, b0, b1, b2, b3)
    Y = node_vectors(state, N)[4]
    if offset:
        # Y = m dP gamma[:, s] = m (theta x p) x gamma[:, s]: G += Lambda Y' + Y Lambda'
        for s in range(n):
            row = params[gam + s * width:gam + (s + 1) * width]
            for j in range(N):
                m = params[ma + j]
                t0, t1, t2 = node_vector(th, N, j)
                c0, c1, c2 = cross3(t0, t1, t2, params[pa + j], params[pa + N + j], params[pa + 2 * N + j])
                g0, g1, g2 = node_vector(row, N, j)
                y0, y1, y2 = cross3(c0, c1, c2, g0, g1, g2)
                store_node_vector(Y, N, j, m * y0, m * y1, m * y2)
            for r in range(n):
                other = params[lam + r * width:lam + (r + 1) * width]
                acc = 0.0
                for k in range(width):
                    acc += other[k] * Y[k]
                G[r, s] += acc
                G[s, r] += acc
