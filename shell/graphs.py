"""The three directed-graph algorithms a scene build needs, without importing networkx (0.12 s of every start):

* :func:`topological_order`: the lexicographic topological order (Kahn's algorithm taking, among the nodes
  whose predecessors are all placed, the one with the smallest key; with distinct keys the order is unique,
  the same as ``networkx.lexicographical_topological_sort``);
* :func:`condensation_order`: the strongly connected components (Tarjan's algorithm, iterative) in the
  lexicographic topological order of the condensed graph, each keyed by its smallest member;
* :func:`find_cycle`: one directed cycle as a list of edges, found by a depth-first search over the nodes and
  their out-edges in insertion order (the walk of ``networkx.find_cycle``: the cycle closes at the first edge
  that reaches a node on the current path, and is reported from that node).

Graphs are given as an insertion-ordered mapping ``node -> list of successors`` (duplicates ignored);
:class:`Digraph` builds one the way the callers add nodes and edges. Tests compare all three with networkx on
random graphs (tests/shell/test_graphs.py).
"""

from __future__ import annotations

import heapq


class CycleError(ValueError):
    """The graph has a directed cycle (no topological order exists)."""


class Digraph:
    """Nodes and out-edges in insertion order; adding an edge adds its end nodes, as networkx's DiGraph."""

    def __init__(self) -> None:
        self.successors: dict = {}

    def add_node(self, node) -> None:
        self.successors.setdefault(node, [])

    def add_edge(self, tail, head) -> None:
        out = self.successors.setdefault(tail, [])
        self.successors.setdefault(head, [])
        if head not in out:
            out.append(head)


def topological_order(successors: dict, key) -> list:
    """Nodes in the lexicographic topological order by ``key`` (ties by insertion order); CycleError if none."""
    rank = {node: i for i, node in enumerate(successors)}
    indegree = dict.fromkeys(successors, 0)
    for heads in successors.values():
        for head in heads:
            indegree[head] += 1
    ready = [(key(node), rank[node], node) for node, d in indegree.items() if d == 0]
    heapq.heapify(ready)
    order = []
    while ready:
        node = heapq.heappop(ready)[2]
        order.append(node)
        for head in successors[node]:
            indegree[head] -= 1
            if indegree[head] == 0:
                heapq.heappush(ready, (key(head), rank[head], head))
    if len(order) != len(successors):
        raise CycleError("the graph has a cycle")
    return order


def strongly_connected_components(successors: dict) -> list[list]:
    """The strongly connected components (lists of nodes), by an iterative Tarjan search."""
    index, low, on_stack, stack, components = {}, {}, set(), [], []
    counter = 0
    for root in successors:
        if root in index:
            continue
        work = [(root, iter(successors[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, heads = work[-1]
            advanced = False
            for head in heads:
                if head not in index:
                    index[head] = low[head] = counter
                    counter += 1
                    stack.append(head)
                    on_stack.add(head)
                    work.append((head, iter(successors[head])))
                    advanced = True
                    break
                if head in on_stack:
                    low[node] = min(low[node], index[head])
            if advanced:
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                components.append(component)
    return components


def condensation_order(successors: dict, key) -> list[list]:
    """The strongly connected components, each a list of its members, in the lexicographic topological order of
    the condensed graph by ``key(members)`` (ties by order of discovery)."""
    components = strongly_connected_components(successors)
    owner = {node: c for c, members in enumerate(components) for node in members}
    condensed = {c: [] for c in range(len(components))}
    for tail, heads in successors.items():
        for head in heads:
            a, b = owner[tail], owner[head]
            if a != b and b not in condensed[a]:
                condensed[a].append(b)
    return [components[c] for c in topological_order(condensed, lambda c: key(components[c]))]


def find_cycle(successors: dict) -> list[tuple] | None:
    """One directed cycle as its edges [(a, b), (b, c), ..., (z, a)], or None when the graph has none.

    Depth-first from each node not yet explored, in insertion order, following out-edges in insertion order;
    the first edge whose head is on the current path closes the cycle, which is reported from that head."""
    explored = set()
    for start in successors:
        if start in explored:
            continue
        path_edges, on_path, seen = [], {start}, {start}
        visited = set()
        stack = [(start, iter(successors[start]))]
        visited.add(start)
        while stack:
            node, heads = stack[-1]
            head = next(heads, None)
            if head is None:
                stack.pop()
                if path_edges:
                    on_path.discard(path_edges.pop()[1])
                continue
            if head in explored:
                continue
            path_edges.append((node, head))
            if head in on_path:
                first = next(i for i, (tail, _) in enumerate(path_edges) if tail == head)
                return path_edges[first:]
            on_path.add(head)
            seen.add(head)
            if head in visited:  # reached again by another path: not on the path, nothing new below it
                path_edges.pop()
                on_path.discard(head)
                continue
            visited.add(head)
            stack.append((head, iter(successors[head])))
        explored.update(seen)
    return None
