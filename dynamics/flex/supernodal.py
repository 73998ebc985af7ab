"""Supernodal sparse L L' and unpivoted L D L' factorizations of symmetric matrices, with
solves for blocks of right-hand sides, for the shift-invert eigen-solver of
:mod:`dynamics.flex.modes`.

Why not CHOLMOD through cholespy (the earlier factorization): that wheel runs CHOLMOD's
simplicial method, one column at a time, so neither the factorization nor the solves use level-3
BLAS; on the 98,826-DOF plate of tests/flex/test_speed.py it factors in 1.7 s and solves at
9.5 ms per right-hand side in blocks of 8. It also hides the factor and refuses an indefinite
matrix, so it cannot count the eigenvalues below a shift (the Sturm check). The method here
(all steps from T. A. Davis, Direct Methods for Sparse Linear Systems, SIAM 2006, chs. 4 and 9,
and J. W. H. Liu, "The multifrontal method for sparse matrix solution: theory and practice",
SIAM Review 34(1), 1992):

1. ordering: METIS nested dissection of the graph whose nodes are sets of DOFs that stay
   together (the coupled DOFs of a grid);
2. symbolic factorization on that graph: the structure of every column of L is its adjacency
   above the diagonal merged with its children's structures in the elimination tree (Liu, SIAM
   J. Matrix Anal. Appl. 11(1), 1990); the tree is postordered, so every subtree is a contiguous
   range of columns;
3. supernodes: chains of nodes with nested structures, then relaxed amalgamation (a child merged
   into its parent when the explicit zeros stay below a share of the merged block; Ashcraft and
   Grimes, ACM TOMS 15(4), 1989; the nrelax/zrelax rule of CHOLMOD);
4. multifrontal factorization: per supernode, a dense frontal matrix gets the entries of A and
   the update matrices of its children (extend-add), then a partial dense factorization, LAPACK
   dpotrf and BLAS dtrsm / dsyrk for L L', an unpivoted dense L D L' kernel and dtrsm / dgemm for
   L D L'; the update matrix goes on a stack for the parent;
5. solves: per supernode, dtrsm and dgemm on the whole block of right-hand sides.

Inertia (Sylvester's law of inertia): the signs of D in L D L' = A are those of the eigenvalues
of A, so for A = K - s M with M positive semi-definite the number of negative pivots is the
number of eigenvalues of (K, M) below s (the Sturm sequence check of Lanczos eigen-solvers;
Grimes, Lewis and Simon, SIAM J. Matrix Anal. Appl. 15(1), 1994, sec. 3; Bathe, Finite Element
Procedures, 1996, sec. 11.4.3). L D L' without pivoting is what those solvers use for this
count; a zero pivot is reported, a tiny one makes the factor inaccurate but leaves its sign.

The BLAS and LAPACK routines are scipy's (scipy.linalg.cython_blas / cython_lapack), called
from the compiled kernels through function pointers passed as arguments, which keeps the
kernels in numba's on-disk cache.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit
from numba.extending import get_cython_function_address


class FactorizationError(ValueError):
    """The matrix cannot be factored as asked (not positive definite, or a zero pivot)."""

    def __init__(self, message: str, dof: int):
        super().__init__(message)
        self.dof = dof


def _routine(module: str, name: str, n_args: int):
    address = get_cython_function_address(f"scipy.linalg.cython_{module}", name)
    return ctypes.CFUNCTYPE(None, *([ctypes.c_void_p] * n_args))(address)


_DPOTRF = _routine("lapack", "dpotrf", 5)
_DTRSM = _routine("blas", "dtrsm", 11)
_DSYRK = _routine("blas", "dsyrk", 10)
_DGEMM = _routine("blas", "dgemm", 13)

# relaxed amalgamation (CHOLMOD's defaults): a merged supernode of at most NRELAX[i] columns may
# hold up to ZRELAX[i] of explicit zeros; larger ones up to ZRELAX[-1]
NRELAX = (4, 16, 48)
ZRELAX = (0.8, 0.1, 0.05)


@dataclass
class Symbolic:
    """The analysis of a sparsity pattern, reusable for every matrix with that pattern.

    Parameters
    ----------
    perm : (n,) original DOF of each factor column; pinv its inverse.
    first, width, n_rows : (ns,) first column, number of columns and of rows below of each
        supernode (in factor order, postordered).
    row_ptr, rows : the rows below every supernode, ascending factor indices.
    value_ptr : (ns + 1,) offset of each supernode's dense (width + n_rows) x width column-major
        block in the factor values.
    n_children : (ns,) children in the supernodal elimination tree.
    front_max, stack_max : largest frontal matrix (entries) and update-matrix stack (entries).
    """

    n: int
    perm: np.ndarray
    pinv: np.ndarray
    first: np.ndarray
    width: np.ndarray
    n_rows: np.ndarray
    row_ptr: np.ndarray
    rows: np.ndarray
    value_ptr: np.ndarray
    n_children: np.ndarray
    front_max: int
    stack_max: int

    @property
    def factor_entries(self) -> int:
        return int(self.value_ptr[-1])


def _node_graph(A: sp.csr_matrix, groups: np.ndarray | None):
    """The graph that is ordered: its nodes are sets of DOFs that stay together.

    With ``groups`` (a label per DOF: its grid), a node is a part of a group whose DOFs share
    neighbours (:func:`_group_parts`: all six DOFs of a shell grid; in a flat plate, whose
    membrane and bending stiffness do not couple, its membrane DOFs and its bending DOFs: two
    nodes and half the fill). Without, a node is a supervariable: DOFs whose rows hold the
    same columns. Returns (ptr, dofs): the DOFs of every node, and (adj_ptr, adj): its
    neighbours.
    """
    A = sp.csr_matrix(A)
    A.sort_indices()
    indptr, indices = A.indptr.astype(np.int64), A.indices.astype(np.int64)
    if groups is None:
        key = _row_hashes(indptr, indices)
        order = np.lexsort((np.diff(indptr), key))
        label = _supervariables(indptr, indices, key, order)
    else:
        _, g = np.unique(np.asarray(groups), return_inverse=True)
        label = _group_parts(indptr, indices, g.astype(np.int64))
    ng = int(label.max()) + 1
    dofs = np.argsort(label, kind="stable").astype(np.int64)
    ptr = np.zeros(ng + 1, dtype=np.int64)
    np.add.at(ptr, label + 1, 1)
    ptr = np.cumsum(ptr)
    adj_ptr, adj = _adjacency(indptr, indices, label, ptr, dofs, ng)
    return ptr, dofs, adj_ptr, adj


@njit(cache=True)
def _group_parts(indptr, indices, g):
    """Label of every DOF: the parts of each group whose DOFs share a neighbour (union-find
    over the DOFs of one group in every row). Sharing a neighbour, not coupling directly: the
    entries between two DOFs of one grid can cancel exactly in a regular mesh and be left out
    of the pattern, while they still couple through the neighbouring grids."""
    n = len(g)
    root = np.arange(n)
    seen = np.full(int(g.max()) + 1 if n else 0, -1, dtype=np.int64)
    stamp = np.full(len(seen), -1, dtype=np.int64)
    for k in range(n):
        for t in range(indptr[k], indptr[k + 1]):
            i = indices[t]
            if stamp[g[i]] != k:
                stamp[g[i]] = k
                seen[g[i]] = i
                continue
            a, b = i, seen[g[i]]
            while root[a] != a:
                a = root[a]
            while root[b] != b:
                b = root[b]
            if a != b:
                root[max(a, b)] = min(a, b)
    label = np.full(n, -1, dtype=np.int64)
    ng = 0
    for i in range(n):
        a = i
        while root[a] != a:
            a = root[a]
        if label[a] == -1:
            label[a] = ng
            ng += 1
        label[i] = label[a]
    return label


@njit(cache=True)
def _row_hashes(indptr, indices):
    """A hash of the set of columns of every row, the diagonal included."""
    n = len(indptr) - 1
    key = np.empty(n, dtype=np.int64)
    for i in range(n):
        h = np.int64(i + 1) * np.int64(0x9E3779B97F4A7C15 & 0x7FFFFFFFFFFFFFFF)
        for k in range(indptr[i], indptr[i + 1]):
            if indices[k] != i:
                h += (np.int64(indices[k]) + 1) * np.int64(0x9E3779B97F4A7C15 & 0x7FFFFFFFFFFFFFFF)
        key[i] = h
    return key


@njit(cache=True)
def _same_columns(indptr, indices, i, j):
    """Rows i and j (sorted columns) hold the same columns once i and j are both counted."""
    a, b = indptr[i], indptr[j]
    ea, eb = indptr[i + 1], indptr[j + 1]
    has_i = has_j = False
    for k in range(a, ea):
        if indices[k] == j:
            has_j = True
    for k in range(b, eb):
        if indices[k] == i:
            has_i = True
    if not (has_i and has_j) or ea - a != eb - b:
        return False
    while a < ea:
        if indices[a] != indices[b]:
            return False
        a += 1
        b += 1
    return True


@njit(cache=True)
def _supervariables(indptr, indices, key, order):
    """Label of every row: rows with the same hash and count are compared exactly."""
    n = len(key)
    label = np.full(n, -1, dtype=np.int64)
    ng = 0
    start = 0
    while start < n:
        end = start + 1
        while end < n and key[order[end]] == key[order[start]] and \
                indptr[order[end] + 1] - indptr[order[end]] == \
                indptr[order[start] + 1] - indptr[order[start]]:
            end += 1
        for a in range(start, end):
            i = order[a]
            if label[i] != -1:
                continue
            label[i] = ng
            for b in range(a + 1, end):
                j = order[b]
                if label[j] == -1 and _same_columns(indptr, indices, i, j):
                    label[j] = ng
            ng += 1
        start = end
    return label


@njit(cache=True)
def _adjacency(indptr, indices, g, gptr, gdofs, ng):
    """Adjacency of the groups (no self loops) from the pattern of A: a marker per group."""
    marker = np.full(ng, -1, dtype=np.int64)
    count = np.zeros(ng + 1, dtype=np.int64)
    for u in range(ng):
        marker[u] = u
        for t in range(gptr[u], gptr[u + 1]):
            i = gdofs[t]
            for k in range(indptr[i], indptr[i + 1]):
                v = g[indices[k]]
                if marker[v] != u:
                    marker[v] = u
                    count[u + 1] += 1
    for u in range(ng):
        count[u + 1] += count[u]
    adj = np.empty(count[ng], dtype=np.int64)
    marker[:] = -1
    for u in range(ng):
        marker[u] = u
        pos = count[u]
        for t in range(gptr[u], gptr[u + 1]):
            i = gdofs[t]
            for k in range(indptr[i], indptr[i + 1]):
                v = g[indices[k]]
                if marker[v] != u:
                    marker[v] = u
                    adj[pos] = v
                    pos += 1
    return count, adj


def _nested_dissection(adj_ptr, adj, weight) -> np.ndarray:
    """Elimination order of the nodes: METIS multilevel nested dissection (Karypis and Kumar,
    SIAM J. Sci. Comput. 20(1), 1998) through pymetis, node weights = their DOFs. On the plate
    of tests/flex/test_speed.py: 9.9M factor entries and 2.0 GFLOP against 10.7M and 2.7 GFLOP
    for SuperLU's multiple minimum degree, in a quarter of the time."""
    ng = len(adj_ptr) - 1
    if ng <= 2 or len(adj) == 0:
        return np.arange(ng, dtype=np.int64)
    import pymetis
    graph = pymetis.CSRAdjacency(adj_ptr.astype(np.int32), adj.astype(np.int32))
    perm, _ = pymetis.nested_dissection(graph, vweights=weight.astype(np.int32))
    return np.asarray(perm, dtype=np.int64)


@njit(cache=True)
def _node_structure(ng, adj_ptr, adj, order):
    """Structure of every column of the node-level factor for elimination ``order``.

    Returns (parent, struct_ptr, struct): parent in the elimination tree (-1 for a root) and
    the rows below the diagonal of each column, ascending, in elimination positions.
    """
    pinv = np.empty(ng, dtype=np.int64)
    for k in range(ng):
        pinv[order[k]] = k
    parent = np.full(ng, -1, dtype=np.int64)
    head = np.full(ng, -1, dtype=np.int64)        # children lists
    nxt = np.full(ng, -1, dtype=np.int64)
    marker = np.full(ng, -1, dtype=np.int64)
    struct_ptr = np.zeros(ng + 1, dtype=np.int64)
    struct = np.empty(max(4 * len(adj), 16), dtype=np.int64)
    buf = np.empty(ng, dtype=np.int64)
    for k in range(ng):
        marker[k] = k
        cnt = 0
        u = order[k]
        for t in range(adj_ptr[u], adj_ptr[u + 1]):
            j = pinv[adj[t]]
            if j > k and marker[j] != k:
                marker[j] = k
                buf[cnt] = j
                cnt += 1
        c = head[k]
        while c != -1:
            for t in range(struct_ptr[c], struct_ptr[c + 1]):
                j = struct[t]
                if j > k and marker[j] != k:
                    marker[j] = k
                    buf[cnt] = j
                    cnt += 1
            c = nxt[c]
        rows = np.sort(buf[:cnt])
        start = struct_ptr[k]
        if start + cnt > len(struct):
            grown = np.empty(max(2 * len(struct), start + cnt), dtype=np.int64)
            grown[:start] = struct[:start]
            struct = grown
        struct[start:start + cnt] = rows
        struct_ptr[k + 1] = start + cnt
        if cnt:
            p = rows[0]
            parent[k] = p
            nxt[k] = head[p]
            head[p] = k
    return parent, struct_ptr, struct[:struct_ptr[ng]].copy()


@njit(cache=True)
def _postorder(parent):
    """Postorder of a forest given by parent pointers (children visited in increasing order)."""
    n = len(parent)
    head = np.full(n, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    for j in range(n - 1, -1, -1):
        p = parent[j]
        if p != -1:
            nxt[j] = head[p]
            head[p] = j
    post = np.empty(n, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    k = 0
    for root in range(n):
        if parent[root] != -1:
            continue
        top = 0
        stack[0] = root
        while top >= 0:
            j = stack[top]
            c = head[j]
            if c == -1:
                top -= 1
                post[k] = j
                k += 1
            else:
                head[j] = nxt[c]
                top += 1
                stack[top] = c
    return post


@njit(cache=True)
def _supernodes(parent, struct_ptr, struct, weight, nrelax, zrelax):
    """Node ranges of the supernodes, first nodes of each plus a closing entry.

    Fundamental supernodes are chains: node j joins node j - 1 when j is its parent, its only
    child, and its structure is the child's minus j. A supernode then merges into its parent
    when it directly precedes it (the parent's last child in postorder) and the merged block,
    whose columns all take the parent's rows, keeps at most ``zrelax`` of explicit zeros for its
    width in DOFs (``nrelax``). ``weight``: DOFs per node.
    """
    ng = len(parent)
    n_child = np.zeros(ng, dtype=np.int64)
    for j in range(ng):
        if parent[j] != -1:
            n_child[parent[j]] += 1
    first = np.empty(ng + 1, dtype=np.int64)
    ns = 0
    for j in range(ng):
        chain = (j > 0 and parent[j - 1] == j and n_child[j] == 1
                 and struct_ptr[j] - struct_ptr[j - 1] == struct_ptr[j + 1] - struct_ptr[j] + 1)
        if not chain:
            first[ns] = j
            ns += 1
    first[ns] = ng
    # DOF columns, DOF rows below, and true entries (grid blocks dense) of every supernode
    width = np.zeros(ns, dtype=np.int64)
    below = np.zeros(ns, dtype=np.int64)
    entries = np.zeros(ns)
    sn_of = np.empty(ng, dtype=np.int64)
    for s in range(ns):
        for j in range(first[s], first[s + 1]):
            sn_of[j] = s
            width[s] += weight[j]
        last = first[s + 1] - 1
        for t in range(struct_ptr[last], struct_ptr[last + 1]):
            below[s] += weight[struct[t]]
        w = width[s]
        entries[s] = 0.5 * w * (w + 1) + w * below[s]
    merged_into = np.full(ns, -1, dtype=np.int64)
    start = first[:ns].copy()
    for s in range(ns - 1):
        last = first[s + 1] - 1
        if parent[last] == -1 or sn_of[parent[last]] != s + 1:
            continue
        w = width[s] + width[s + 1]
        stored = 0.5 * w * (w + 1) + w * below[s + 1]
        zeros = (stored - entries[s] - entries[s + 1]) / stored
        ok = zeros < zrelax[len(zrelax) - 1]
        for level in range(len(nrelax)):
            if w <= nrelax[level]:
                ok = zeros < zrelax[level]
                break
        if ok:
            merged_into[s] = s + 1
            width[s + 1] = w
            entries[s + 1] += entries[s]
            start[s + 1] = start[s]
    out = np.empty(ns + 1, dtype=np.int64)
    m = 0
    for s in range(ns):
        if merged_into[s] == -1:
            out[m] = start[s]
            m += 1
    out[m] = ng
    return out[:m + 1].copy()


@njit(cache=True)
def _supernode_layout(sn_first, parent, struct_ptr, struct, weight):
    """DOF-level layout: first column, width and rows below of every supernode, its rows, the
    offsets of its dense block, its children count, the largest front and the stack peak."""
    ns = len(sn_first) - 1
    ng = len(parent)
    dof_first = np.zeros(ng + 1, dtype=np.int64)
    for k in range(ng):
        dof_first[k + 1] = dof_first[k] + weight[k]
    sn_of = np.empty(ng, dtype=np.int64)
    first = np.empty(ns, dtype=np.int64)
    width = np.empty(ns, dtype=np.int64)
    n_rows = np.zeros(ns, dtype=np.int64)
    for s in range(ns):
        first[s] = dof_first[sn_first[s]]
        width[s] = dof_first[sn_first[s + 1]] - first[s]
        for j in range(sn_first[s], sn_first[s + 1]):
            sn_of[j] = s
        last = sn_first[s + 1] - 1
        for t in range(struct_ptr[last], struct_ptr[last + 1]):
            n_rows[s] += weight[struct[t]]
    row_ptr = np.zeros(ns + 1, dtype=np.int64)
    value_ptr = np.zeros(ns + 1, dtype=np.int64)
    for s in range(ns):
        row_ptr[s + 1] = row_ptr[s] + n_rows[s]
        value_ptr[s + 1] = value_ptr[s] + (width[s] + n_rows[s]) * width[s]
    rows = np.empty(row_ptr[ns], dtype=np.int64)
    n_children = np.zeros(ns, dtype=np.int64)
    front_max = 0
    stack = 0
    stack_max = 0
    for s in range(ns):
        last = sn_first[s + 1] - 1
        pos = row_ptr[s]
        for t in range(struct_ptr[last], struct_ptr[last + 1]):
            j = struct[t]
            for d in range(dof_first[j], dof_first[j + 1]):
                rows[pos] = d
                pos += 1
        if parent[last] != -1:
            n_children[sn_of[parent[last]]] += 1
        f = width[s] + n_rows[s]
        front_max = max(front_max, f * f)
    # the update stack in postorder: a supernode pops its children, then pushes its own
    sizes = np.empty(ns, dtype=np.int64)
    depth = 0
    for s in range(ns):
        for _ in range(n_children[s]):
            depth -= 1
            stack -= sizes[depth]
        sizes[depth] = n_rows[s] * n_rows[s]
        stack += sizes[depth]
        depth += 1
        stack_max = max(stack_max, stack)
    return first, width, n_rows, row_ptr, rows, value_ptr, n_children, front_max, stack_max


@njit(cache=True)
def _expand(ptr, order):
    """Positions ptr[u]..ptr[u + 1] of every node u, nodes in ``order``."""
    out = np.empty(ptr[-1], dtype=np.int64)
    k = 0
    for u in order:
        for t in range(ptr[u], ptr[u + 1]):
            out[k] = t
            k += 1
    return out


def analyse(A, groups: np.ndarray | None = None) -> Symbolic:
    """Ordering, elimination tree, supernodes and storage of the factor of ``A`` (its pattern,
    symmetric, diagonal present) on the graph of :func:`_node_graph` (``groups``: the grid of
    every DOF, if known)."""
    A = sp.csr_matrix(A)
    n = A.shape[0]
    gptr, gdofs, adj_ptr, adj = _node_graph(A, groups)
    ng = len(gptr) - 1
    order = _nested_dissection(adj_ptr, adj, np.diff(gptr))
    parent, _, _ = _node_structure(ng, adj_ptr, adj, order)
    order = order[_postorder(parent)]
    parent, struct_ptr, struct = _node_structure(ng, adj_ptr, adj, order)
    weight = np.diff(gptr)[order]
    sn_first = _supernodes(parent, struct_ptr, struct, weight, np.array(NRELAX, dtype=np.int64),
                           np.array(ZRELAX))
    (first, width, n_rows, row_ptr, rows, value_ptr, n_children, front_max,
     stack_max) = _supernode_layout(sn_first, parent, struct_ptr, struct, weight)
    perm = gdofs[_expand(gptr, order)]
    pinv = np.empty(n, dtype=np.int64)
    pinv[perm] = np.arange(n)
    return Symbolic(n, perm, pinv, first, width, n_rows, row_ptr, rows, value_ptr, n_children,
                    int(front_max), int(stack_max))


# LAPACK/BLAS character arguments
_L, _N, _T, _R, _U = (ord(c) for c in "LNTRU")


@njit(cache=True)
def _trsm(fn, side, trans, diag, m, n, A, a_off, lda, B, b_off, ldb):
    """B := B op(A)^-1 (side R) with A lower triangular, column-major (dtrsm)."""
    chars = np.array([side, _L, trans, diag], dtype=np.uint8)
    ints = np.array([m, n, lda, ldb], dtype=np.int32)
    one = np.ones(1)
    fn(chars[0:].ctypes, chars[1:].ctypes, chars[2:].ctypes, chars[3:].ctypes, ints[0:].ctypes,
       ints[1:].ctypes, one.ctypes, A[a_off:].ctypes, ints[2:].ctypes, B[b_off:].ctypes,
       ints[3:].ctypes)


@njit(cache=True)
def _gemm(fn, ta, tb, m, n, k, alpha, A, a_off, lda, B, b_off, ldb, beta, C, c_off, ldc):
    """C := alpha op(A) op(B) + beta C, column-major (dgemm)."""
    chars = np.array([ta, tb], dtype=np.uint8)
    ints = np.array([m, n, k, lda, ldb, ldc], dtype=np.int32)
    scal = np.array([alpha, beta])
    fn(chars[0:].ctypes, chars[1:].ctypes, ints[0:].ctypes, ints[1:].ctypes, ints[2:].ctypes,
       scal[0:].ctypes, A[a_off:].ctypes, ints[3:].ctypes, B[b_off:].ctypes, ints[4:].ctypes,
       scal[1:].ctypes, C[c_off:].ctypes, ints[5:].ctypes)


@njit(cache=True)
def _numeric(indptr, indices, data, perm, pinv, first, width, n_rows, row_ptr, rows, value_ptr,
             n_children, front_max, stack_max, ldl, dpotrf, dtrsm, dsyrk, dgemm):
    """Multifrontal L L' (``ldl`` False) or unpivoted L D L' of the symmetric matrix A (CSR,
    original numbering) in the layout of the analysis.

    Returns (values, d, status): the supernode blocks (column-major, unit lower for L D L'), D
    (L D L') or diag(L)^2 (L L'), and -1 when done, else the factor column where a pivot was
    not positive (L L') or zero (L D L').
    """
    n = len(perm)
    ns = len(first)
    values = np.empty(value_ptr[ns])
    d = np.empty(n)
    front = np.empty(front_max)
    stack = np.empty(max(stack_max, 1))
    stack_sizes = np.empty(ns, dtype=np.int64)
    stack_owner = np.empty(ns, dtype=np.int64)
    depth = 0
    top = 0
    local = np.full(n, -1, dtype=np.int64)
    info = np.zeros(1, dtype=np.int32)
    ints = np.zeros(2, dtype=np.int32)
    chars = np.array([_L, _N], dtype=np.uint8)
    scal = np.array([-1.0, 1.0])
    work = np.empty(front_max)
    for s in range(ns):
        c0, w, r = first[s], width[s], n_rows[s]
        f = w + r
        for t in range(w):
            local[c0 + t] = t
        for t in range(r):
            local[rows[row_ptr[s] + t]] = w + t
        F = front[:f * f]
        F[:] = 0.0
        for t in range(w):
            j = c0 + t
            jo = perm[j]
            for k in range(indptr[jo], indptr[jo + 1]):
                i = pinv[indices[k]]
                if i >= j:
                    F[local[i] + f * t] += data[k]
        for _ in range(n_children[s]):
            depth -= 1
            c = stack_owner[depth]
            rc = n_rows[c]
            top -= stack_sizes[depth]
            base = row_ptr[c]
            for b in range(rc):
                lb = local[rows[base + b]]
                col = top + rc * b
                for a in range(b, rc):
                    F[local[rows[base + a]] + f * lb] += stack[col + a]
        if ldl:
            # unpivoted L D L' of the diagonal block in place (right-looking, column-major)
            for k in range(w):
                piv = F[k + f * k]
                if piv == 0.0:
                    return values, d, c0 + k
                d[c0 + k] = piv
                for j in range(k + 1, w):
                    ljk = F[j + f * k] / piv
                    if ljk != 0.0:
                        for i in range(j, w):
                            F[i + f * j] -= F[i + f * k] * ljk
                for i in range(k + 1, w):
                    F[i + f * k] /= piv
            if r:
                # F21 L11^-T = L21 D (kept in work), L21 = that D^-1, F22 -= (L21 D) L21'
                _trsm(dtrsm, _R, _T, _U, r, w, F, 0, f, F, w, f)
                for t in range(w):
                    for i in range(r):
                        work[i + r * t] = F[w + i + f * t]
                        F[w + i + f * t] /= d[c0 + t]
                _gemm(dgemm, _N, _T, r, r, w, -1.0, work, 0, r, F, w, f, 1.0, F, w + f * w, f)
        else:
            ints[0] = w
            ints[1] = f
            dpotrf(chars[0:].ctypes, ints[0:].ctypes, F.ctypes, ints[1:].ctypes, info.ctypes)
            if info[0] != 0:
                return values, d, c0 + info[0] - 1
            for k in range(w):
                d[c0 + k] = F[k + f * k] * F[k + f * k]
            if r:
                _trsm(dtrsm, _R, _T, _N, r, w, F, 0, f, F, w, f)
                ints[0] = r
                ints[1] = w
                fints = np.array([f, f], dtype=np.int32)
                dsyrk(chars[0:].ctypes, chars[1:].ctypes, ints[0:].ctypes, ints[1:].ctypes,
                      scal[0:].ctypes, F[w:].ctypes, fints[0:].ctypes, scal[1:].ctypes,
                      F[w + f * w:].ctypes, fints[1:].ctypes)
        values[value_ptr[s]:value_ptr[s + 1]] = F[:f * w]
        if r:
            for b in range(r):
                for a in range(b, r):
                    stack[top + a + r * b] = F[w + a + f * (w + b)]
            stack_sizes[depth] = r * r
            stack_owner[depth] = s
            top += r * r
            depth += 1
        else:
            stack_sizes[depth] = 0
            stack_owner[depth] = s
            depth += 1
    return values, d, -1


@njit(cache=True)
def _solve(X, first, width, n_rows, row_ptr, rows, value_ptr, values, d, ldl, dtrsm, dgemm):
    """X := A^-1 X in place (factor order, n x p C-ordered): forward and back substitution by
    supernodes. A C-ordered row block of X is a column-major p x w block, so every supernode is
    one dtrsm and one dgemm from the right, the rows below gathered into (or scattered from) a
    work block. The BLAS arguments live in buffers filled in place: most supernodes of a shell
    model are a few columns wide, and allocating them per call cost 15 % of a block solve.
    (Compiled loops instead of BLAS for the narrow supernodes were slower.)"""
    n, p = X.shape
    ns = len(first)
    flat = X.reshape(n * p)
    work = np.empty(max(np.max(n_rows), 1) * p)
    # characters: side R, uplo L, trans T, diag, trans N; integers m, n, k, lda, ldb, ldc;
    # scalars 1, 0, -1
    ch = np.array([_R, _L, _T, _U if ldl else _N, _N], dtype=np.uint8)
    it = np.zeros(6, dtype=np.int32)
    sc = np.array([1.0, 0.0, -1.0])
    for s in range(ns):
        c0, w, r = first[s], width[s], n_rows[s]
        f, v0 = w + r, value_ptr[s]
        it[0], it[1], it[3], it[4] = p, w, f, p
        dtrsm(ch[0:].ctypes, ch[1:].ctypes, ch[2:].ctypes, ch[3:].ctypes, it[0:].ctypes,
              it[1:].ctypes, sc[0:].ctypes, values[v0:].ctypes, it[3:].ctypes,
              flat[c0 * p:].ctypes, it[4:].ctypes)
        if r:
            it[0], it[1], it[2], it[3], it[4], it[5] = p, r, w, p, f, p
            dgemm(ch[4:].ctypes, ch[2:].ctypes, it[0:].ctypes, it[1:].ctypes, it[2:].ctypes,
                  sc[0:].ctypes, flat[c0 * p:].ctypes, it[3:].ctypes, values[v0 + w:].ctypes,
                  it[4:].ctypes, sc[1:].ctypes, work.ctypes, it[5:].ctypes)
            base = row_ptr[s]
            for a in range(r):
                xr = X[rows[base + a]]
                for j in range(p):
                    xr[j] -= work[j + p * a]
    if ldl:
        for i in range(n):
            inv = 1.0 / d[i]
            for j in range(p):
                X[i, j] *= inv
    for s in range(ns - 1, -1, -1):
        c0, w, r = first[s], width[s], n_rows[s]
        f, v0 = w + r, value_ptr[s]
        if r:
            base = row_ptr[s]
            for a in range(r):
                xr = X[rows[base + a]]
                for j in range(p):
                    work[j + p * a] = xr[j]
            it[0], it[1], it[2], it[3], it[4], it[5] = p, w, r, p, f, p
            dgemm(ch[4:].ctypes, ch[4:].ctypes, it[0:].ctypes, it[1:].ctypes, it[2:].ctypes,
                  sc[2:].ctypes, work.ctypes, it[3:].ctypes, values[v0 + w:].ctypes,
                  it[4:].ctypes, sc[0:].ctypes, flat[c0 * p:].ctypes, it[5:].ctypes)
        it[0], it[1], it[3], it[4] = p, w, f, p
        dtrsm(ch[0:].ctypes, ch[1:].ctypes, ch[4:].ctypes, ch[3:].ctypes, it[0:].ctypes,
              it[1:].ctypes, sc[0:].ctypes, values[v0:].ctypes, it[3:].ctypes,
              flat[c0 * p:].ctypes, it[4:].ctypes)


class SupernodalFactor:
    """A = L L' (``ldl`` False: A positive definite) or A = L D L' (unpivoted), with
    ``solve(b)`` for a vector or an n x p block.

    ``symbolic``: a previous analysis of the same pattern (e.g. K - s M for another s).
    ``pivots``: D, or diag(L)^2, in factor order; ``inertia``: (negative, zero, positive)
    pivots. Raises :class:`FactorizationError` naming the original DOF of a pivot that is not
    positive (L L') or is zero (L D L').
    """

    method = "supernodal Cholesky (multifrontal, METIS nested dissection of the grids, BLAS-3)"

    def __init__(self, A, groups: np.ndarray | None = None, ldl: bool = False,
                 symbolic: Symbolic | None = None):
        A = sp.csr_matrix(A)
        self.n = A.shape[0]
        self.ldl = ldl
        self.symbolic = symbolic if symbolic is not None else analyse(A, groups)
        S = self.symbolic
        values, d, status = _numeric(
            A.indptr.astype(np.int64), A.indices.astype(np.int64), A.data.astype(float),
            S.perm, S.pinv, S.first, S.width, S.n_rows, S.row_ptr, S.rows, S.value_ptr,
            S.n_children, S.front_max, S.stack_max, ldl, _DPOTRF, _DTRSM, _DSYRK, _DGEMM)
        if status >= 0:
            dof = int(S.perm[status])
            kind = "zero pivot" if ldl else "not positive definite"
            raise FactorizationError(f"{kind} at DOF {dof} (factor column {status})", dof)
        self.values = values
        self.pivots = d

    @property
    def inertia(self) -> tuple[int, int, int]:
        return (int(np.sum(self.pivots < 0.0)), int(np.sum(self.pivots == 0.0)),
                int(np.sum(self.pivots > 0.0)))

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        X = np.ascontiguousarray(b[self.symbolic.perm] if b.ndim == 2 else
                                 b[self.symbolic.perm, None])
        S = self.symbolic
        _solve(X, S.first, S.width, S.n_rows, S.row_ptr, S.rows, S.value_ptr, self.values,
               self.pivots, self.ldl, _DTRSM, _DGEMM)
        x = np.empty_like(X)
        x[S.perm] = X
        return x if b.ndim == 2 else x[:, 0]
