"""shell.graphs (the scene build's graph algorithms, written to spare every start networkx's import) against
networkx itself on random graphs: the same topological orders, the same condensation order, the same cycle."""

import random

import networkx as nx
import pytest

from shell.graphs import CycleError, Digraph, condensation_order, find_cycle, topological_order


def _random_graph(rng, n, p, acyclic):
    ours, theirs = Digraph(), nx.DiGraph()
    nodes = list(range(n))
    rng.shuffle(nodes)                                   # insertion order differs from the labels
    for v in nodes[: n // 2]:
        ours.add_node(v)
        theirs.add_node(v)
    for _ in range(int(p * n * n)):
        a, b = rng.randrange(n), rng.randrange(n)
        if a == b or (acyclic and a > b):
            continue
        ours.add_edge(a, b)
        theirs.add_edge(a, b)
        if rng.random() < 0.1:
            ours.add_edge(a, b)                          # a repeated edge is one edge
            theirs.add_edge(a, b)
    return ours, theirs


@pytest.mark.parametrize("seed", range(40))
def test_same_as_networkx(seed):
    rng = random.Random(seed)
    n = rng.randrange(1, 30)
    key = {v: rng.random() for v in range(n)}.__getitem__
    ours, theirs = _random_graph(rng, n, rng.choice([0.02, 0.05, 0.1]), acyclic=True)
    assert list(ours.successors) == list(theirs.nodes)
    assert topological_order(ours.successors, key) == list(nx.lexicographical_topological_sort(theirs, key=key))
    assert find_cycle(ours.successors) is None

    ours, theirs = _random_graph(rng, n, rng.choice([0.02, 0.05, 0.1, 0.2]), acyclic=False)
    try:
        expected = nx.find_cycle(theirs)
    except nx.NetworkXNoCycle:
        expected = None
    assert find_cycle(ours.successors) == expected
    if expected is not None:
        with pytest.raises(CycleError):
            topological_order(ours.successors, key)
    condensed = nx.condensation(theirs)
    expected_order = [sorted(condensed.nodes[c]["members"]) for c in nx.lexicographical_topological_sort(
        condensed, key=lambda c: min(condensed.nodes[c]["members"]))]
    assert [sorted(c) for c in condensation_order(ours.successors, min)] == expected_order
