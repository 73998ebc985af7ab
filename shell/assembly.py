"""Hierarchical assemblies of models: composition by named ports (Dshell assemblies, Drake Diagram).

An :class:`Assembly` holds child models and sub-assemblies, the connections between their ports
(dotted names relative to the assembly, ``"controller.torque" -> "plant.torque"``), the inner ports
it exposes under its own names, and attachments of children to nodes or hinges of an engine model
(TM-2020-5008164 App. D.1: reusable sub-system patterns). :func:`flatten` turns a tree into the flat
list of models and resolved port-to-port connections the :class:`shell.simulation.Simulation` needs.

Reusable assemblies subclass :class:`Assembly`, declare ``parameters`` like a model, build their
children in :meth:`Assembly.build`, and register with :func:`shell.registry.register_model`.
"""

from __future__ import annotations

from dataclasses import dataclass

from shell.model import Model, ModelError, convert_parameters


@dataclass(frozen=True)
class Connection:
    """A resolved connection between a model output and a model input (both by path)."""

    source_model: Model
    source_port: str
    destination_model: Model
    destination_port: str
    origin: str  # how the user wrote it, for error messages


@dataclass(frozen=True)
class _Attachment:
    child: str
    engine: str
    kind: str  # "node" | "hinge"
    target: str
    origin: str | None = None


class Assembly:
    """A named container of models and assemblies with exposed ports."""

    parameters: tuple = ()
    summary: str = ""

    def __init__(self, name: str, **parameter_values):
        if not name or "." in name:
            raise ModelError(f"assembly name {name!r}: use letters, digits and underscores (no dots)")
        self.name = name
        self.path = name
        self.children: dict[str, Model | Assembly] = {}
        self.connections: list[tuple[str, str, str | None]] = []
        self.exposed_inputs: dict[str, list[str]] = {}
        self.exposed_outputs: dict[str, str] = {}
        self.attachments: list[_Attachment] = []
        own = {k: v for k, v in parameter_values.items() if "." not in k}
        self._child_overrides: dict[str, dict] = {}
        for key, value in parameter_values.items():
            if "." in key:
                child, rest = key.split(".", 1)
                self._child_overrides.setdefault(child, {})[rest] = value
        self.parameter_values = convert_parameters(self.parameters, own, f"assembly {name}", type(self).__name__)
        self.build()
        unused = sorted(set(self._child_overrides) - set(self.children))
        if unused:
            raise ModelError(f"assembly {name}: parameter overrides for unknown member(s) {unused}; "
                             f"members: {sorted(self.children)}")

    # -- construction -------------------------------------------------------------------------------
    def build(self) -> None:
        """Create children, connections and exposed ports (reusable assemblies override this)."""

    def child_parameters(self, child_name: str, **defaults) -> dict:
        """``defaults`` updated with user overrides written as ``child.parameter`` on this assembly."""
        merged = dict(defaults)
        merged.update(self._child_overrides.get(child_name, {}))
        return merged

    def parameter(self, name: str):
        return self.parameter_values[name]

    def add(self, child: "Model | Assembly") -> "Model | Assembly":
        if child.name in self.children:
            raise ModelError(f"assembly {self.path}: a member named {child.name!r} already exists")
        self.children[child.name] = child
        return child

    def connect(self, source: str, destination: str, origin: str | None = None) -> None:
        """Connect output ``source`` to input ``destination`` (dotted paths relative to this assembly);
        ``origin`` (e.g. "scene.yaml:12") is quoted in error messages."""
        self.connections.append((source, destination, origin))

    def expose_input(self, name: str, *inner_inputs: str) -> None:
        """Make inner input(s) reachable as ``<assembly>.<name>`` (fan-out to every inner input)."""
        self.exposed_inputs.setdefault(name, []).extend(inner_inputs)

    def expose_output(self, name: str, inner_output: str) -> None:
        self.exposed_outputs[name] = inner_output

    def attach(self, child: str, *, engine: str = "multibody", node: str | None = None,
               hinge: str | None = None, origin: str | None = None) -> None:
        """Bind ``child``'s ports to a node or hinge of ``engine``: child inputs named like the
        engine's node/hinge signals (attitude, angular_velocity, ...) are fed from it, and child outputs
        named like its inputs (force, torque, ...) drive it."""
        if (node is None) == (hinge is None):
            raise ModelError(f"assembly {self.path}: attach {child!r} to exactly one of node= or hinge=")
        kind, target = ("node", node) if node is not None else ("hinge", hinge)
        self.attachments.append(_Attachment(child, engine, kind, target, origin))

    # -- queries ------------------------------------------------------------------------------------
    def input_names(self) -> list[str]:
        return list(self.exposed_inputs)

    def output_names(self) -> list[str]:
        return list(self.exposed_outputs)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.path!r})"


def _member_names(member) -> tuple[list[str], list[str]]:
    if isinstance(member, Model):
        return [p.name for p in member.inputs], [p.name for p in member.outputs]
    return member.input_names(), member.output_names()


def _label(assembly: Assembly) -> str:
    return f"assembly {assembly.path}" if assembly.path else "the scene"


def _split(assembly: Assembly, endpoint: str, what: str) -> tuple[object, str]:
    head, _, rest = endpoint.partition(".")
    if head not in assembly.children:
        if not rest and what == "output" and head in assembly.exposed_outputs:
            return assembly, head
        raise ModelError(f"{what} {endpoint!r}: {_label(assembly)} has no member {head!r}; "
                         f"members: {sorted(assembly.children)}")
    if not rest:
        raise ModelError(f"{what} {endpoint!r} in {_label(assembly)} names a member, not a port "
                         f"(write {head}.<port>)")
    return assembly.children[head], rest


def resolve_output(assembly: Assembly, endpoint: str) -> tuple[Model, str]:
    """The (model, output port) that ``endpoint`` (relative to ``assembly``) denotes."""
    member, rest = _split(assembly, endpoint, "output")
    if isinstance(member, Model):
        if rest not in {p.name for p in member.outputs}:
            kind = "an input" if rest in {p.name for p in member.inputs} else "not a port"
            raise ModelError(f"output {member.path}.{rest}: {kind} of {type(member).__name__}"
                             f"{member.missing_port_hint(rest)}; outputs: {[p.name for p in member.outputs]}")
        return member, rest
    if member is assembly:
        return resolve_output(assembly, assembly.exposed_outputs[rest])
    if rest in member.exposed_outputs:
        return resolve_output(member, member.exposed_outputs[rest])
    if "." in rest and rest.split(".", 1)[0] in member.children:
        return resolve_output(member, rest)
    raise ModelError(f"output {member.path}.{rest}: assembly {member.path} exposes outputs "
                     f"{sorted(member.exposed_outputs)}")


def resolve_inputs(assembly: Assembly, endpoint: str) -> list[tuple[Model, str]]:
    """Every (model, input port) that ``endpoint`` feeds (an exposed input may fan out)."""
    member, rest = _split(assembly, endpoint, "input")
    if isinstance(member, Model):
        if rest not in {p.name for p in member.inputs}:
            kind = "an output" if rest in {p.name for p in member.outputs} else "not a port"
            raise ModelError(f"input {member.path}.{rest}: {kind} of {type(member).__name__}; inputs: "
                             f"{[p.name for p in member.inputs]}")
        return [(member, rest)]
    if rest in member.exposed_inputs:
        resolved = []
        for inner in member.exposed_inputs[rest]:
            resolved.extend(resolve_inputs(member, inner))
        return resolved
    if "." in rest and rest.split(".", 1)[0] in member.children:
        return resolve_inputs(member, rest)
    raise ModelError(f"input {member.path}.{rest}: assembly {member.path} exposes inputs "
                     f"{sorted(member.exposed_inputs)}")


def flatten(root: Assembly) -> tuple[list[Model], list[Connection]]:
    """All models of the tree (paths set to dotted names from the root's children) and the
    connections with every endpoint resolved to a model port."""
    models: list[Model] = []
    connections: list[Connection] = []

    def visit(assembly: Assembly, prefix: str) -> None:
        for child in assembly.children.values():
            child.path = prefix + child.name
            if isinstance(child, Model):
                models.append(child)
            else:
                visit(child, child.path + ".")
        where = assembly.path if prefix else "scenario"
        for source, destination, origin in assembly.connections:
            try:
                src_model, src_port = resolve_output(assembly, source)
                destinations = resolve_inputs(assembly, destination)
            except ModelError as exc:
                raise ModelError(f"{origin or where}: connection {source} -> {destination}: {exc}") from None
            for dst_model, dst_port in destinations:
                resolved = f"{src_model.path}.{src_port} -> {dst_model.path}.{dst_port}"
                written = f"{prefix}{source} -> {prefix}{destination}"
                label = origin or where
                if written != resolved:
                    label += f", written {source} -> {destination}"
                connections.append(Connection(src_model, src_port, dst_model, dst_port, label))
        for attachment in assembly.attachments:
            connections.extend(_bind_attachment(assembly, attachment, connections, where))

    root.path = ""
    visit(root, "")
    return models, connections


def _bind_attachment(assembly: Assembly, attachment: _Attachment, existing: list[Connection],
                     where: str) -> list[Connection]:
    where = attachment.origin or where
    if attachment.child not in assembly.children:
        raise ModelError(f"{where}: cannot attach {attachment.child!r}: no such member; members: "
                         f"{sorted(assembly.children)}")
    if attachment.engine not in assembly.children or not isinstance(assembly.children[attachment.engine], Model):
        raise ModelError(f"{where}: attach {attachment.child} to {attachment.kind} {attachment.target!r}: "
                         f"no engine model named {attachment.engine!r} here")
    engine = assembly.children[attachment.engine]
    child = assembly.children[attachment.child]
    try:
        engine_outputs, engine_inputs = engine.attachment_ports(attachment.kind, attachment.target)
    except ModelError as exc:
        raise ModelError(f"{where}: attach {attachment.child} to {attachment.kind} {attachment.target}: {exc}") from None
    child_inputs, child_outputs = _member_names(child)
    driven = {(c.destination_model.path, c.destination_port) for c in existing}
    origin = f"{where}: attach {attachment.child} to {attachment.engine} {attachment.kind} {attachment.target}"
    bound: list[Connection] = []
    for signal in child_inputs:
        if signal in engine_outputs:
            for dst_model, dst_port in resolve_inputs(assembly, f"{attachment.child}.{signal}"):
                if (dst_model.path, dst_port) not in driven:
                    bound.append(Connection(engine, engine_outputs[signal], dst_model, dst_port, origin))
    for signal in child_outputs:
        if signal in engine_inputs:
            src_model, src_port = resolve_output(assembly, f"{attachment.child}.{signal}")
            _refuse_second_use(src_model, src_port, existing, origin, engine, engine_inputs[signal])
            bound.append(Connection(src_model, src_port, engine, engine_inputs[signal], origin))
    if not bound:
        raise ModelError(f"{origin}: binds no port; {attachment.child} has inputs {child_inputs} and outputs "
                         f"{child_outputs}, the {attachment.kind} offers outputs {sorted(engine_outputs)} "
                         f"and inputs {sorted(engine_inputs)}")
    return bound


def _refuse_second_use(src_model: Model, src_port: str, existing: list[Connection], origin: str, engine: Model,
                       engine_input: str) -> None:
    """An output that ``attach`` would apply to the engine (a force, a torque) and that is also wired to
    another model acts twice: a controller's torque applied to the bus and also commanded to the wheels
    that turn it into torque on the bus. Refused; a scene that means both sums them in a model."""
    for c in existing:
        if c.source_model is src_model and c.source_port == src_port and c.destination_model is not engine:
            raise ModelError(f"{origin}: would apply {src_model.path}.{src_port} to {engine.path}.{engine_input}, "
                             f"but {src_model.path}.{src_port} also drives {c.destination_model.path}."
                             f"{c.destination_port} ({c.origin}): the {src_port} would act twice. Wire the "
                             f"{src_model.path} inputs with connections instead of attach, or route both "
                             "through a model that sums them explicitly")
