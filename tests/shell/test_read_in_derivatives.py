"""Which outputs a derivative evaluation reads (:meth:`shell.diagram.Diagram.read_in_derivatives`): a connection to a
model with continuous states, or to a feedthrough input whose stage the derivatives need (a chain of feedthrough
blocks ending in one); not one to a sampled model, directly or through feedthrough blocks. The diagram tells each
source model when it is built (:meth:`shell.model.Model.output_read`, ``in_derivatives``): what the engine model uses
to compute between samples only the nodes a derivative reads (tests/flexible/test_nodes_read.py)."""

from __future__ import annotations

from shell.assembly import Assembly
from shell.diagram import Diagram, stage_kernel
from shell.models.blocks import Constant, Gain, Integrator, SampleHold


class Recording(Constant):
    """A constant that records what the diagram says is read of it."""

    def output_read(self, name, in_derivatives=False):
        self.reads = getattr(self, "reads", []) + [(name, in_derivatives)]
        return False


def scene():
    root = Assembly("root")
    for name in ("direct", "chained", "sampled", "sampled_chain"):
        root.add(Recording(name, value=1.0))
    root.add(Integrator("integral", unit="s"))  # continuous (input s/s): its derivatives read its input
    root.add(Gain("k", k=2.0))                  # feedthrough, feeding a continuous state
    root.add(Integrator("integral_k", unit="s"))
    root.add(SampleHold("hold", period="10 Hz"))  # sampled: reads its input only at its samples
    root.add(Gain("k_hold", k=3.0))             # feedthrough, feeding only a sampled model
    root.add(SampleHold("hold_k", period="10 Hz"))
    root.connect("direct.y", "integral.u")
    root.connect("chained.y", "k.u")
    root.connect("k.y", "integral_k.u")
    root.connect("sampled.y", "hold.u")
    root.connect("sampled_chain.y", "k_hold.u")
    root.connect("k_hold.y", "hold_k.u")
    return root


def test_the_diagram_tells_each_source_which_of_its_outputs_derivatives_read():
    diagram = Diagram(scene())
    read = {(c.source_model.path, c.destination_model.path): r
            for c, r in zip(diagram.connections, diagram.read_in_derivatives())}
    assert read == {("direct", "integral"): True, ("chained", "k"): True, ("k", "integral_k"): True,
                    ("sampled", "hold"): False, ("sampled_chain", "k_hold"): False, ("k_hold", "hold_k"): False}
    models = {m.path: m for m in diagram.models}
    assert models["direct"].reads == [("y", True)]
    assert models["chained"].reads == [("y", True)]
    assert models["sampled"].reads == [("y", False)]
    assert models["sampled_chain"].reads == [("y", False)]
    # a model without kernels of its own for derivative evaluations runs its ordinary ones there
    k = models["k"]
    assert stage_kernel(k, "feedthrough", True) is k.feedthrough_outputs
