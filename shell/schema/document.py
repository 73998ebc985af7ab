"""Reading a scenario's text: YAML with the line of every mapping, key and list item, within limits.

A scenario is a short UTF-8 YAML text (docs/scenario_schema.md). :func:`load_yaml` reads it with
:class:`LineLoader`, a ``yaml.SafeLoader`` that builds :class:`LineDict` and :class:`LineList` (plain
``dict`` and ``list`` that remember the 1-based line of themselves and of each key or item, so that every
later refusal can name ``file:line: key.path``), refuses duplicate keys and keys that are not names, and
bounds what a hostile file can cost: nesting (``MAX_DEPTH``), expansion through aliases (``MAX_NODES``, a
"billion laughs" document) and size (``MAX_BYTES``).

One extension of YAML: inside a flow mapping or list (``{...}``, ``[...]``) a signal name with an element index,
``{signal: multibody.array.q[0], crosses: 90 deg}``, reads as the text ``multibody.array.q[0]``. Plain YAML stops
the text at ``[`` (a flow indicator) and refuses the document, so no valid YAML document changes meaning: the index
is taken into the text only when ``[`` follows a name character directly and ``[digits]`` closes it.
"""

from __future__ import annotations

import re

import yaml

from shell.units import short_repr


class ScenarioError(ValueError):
    """An invalid scenario; the message starts with ``file:line: key.path:``."""


#: deepest nesting of lists and mappings a scenario may have (deeper: refused, not a RecursionError)
MAX_DEPTH = 48
#: most YAML nodes a scenario may expand to once aliases are followed (an alias bomb is refused)
MAX_NODES = 200_000
#: largest scenario file read (a scenario is a short text; a larger file is refused, not parsed for minutes)
MAX_BYTES = 16 * 2**20


def show(value) -> str:
    """``repr(value)`` cut to a line (:func:`shell.units.short_repr`)."""
    return short_repr(value)


class LineDict(dict):
    """A mapping that remembers the line of itself and of each key (1-based)."""

    line = 0
    lines: dict


class LineList(list):
    """A sequence that remembers the line of itself and of each item (1-based)."""

    line = 0
    lines: list


def plain(value):
    """LineDict/LineList -> dict/list, recursively (picklable, comparable, what ``yaml.safe_dump`` writes)."""
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [plain(v) for v in value]
    return value


def type_name(value) -> str:
    """What a YAML value is, in a user's words (mapping, list, text, number, ...), for messages."""
    return {dict: "mapping", LineDict: "mapping", list: "list", LineList: "list", str: "text", int: "integer",
            float: "number", bool: "boolean", type(None): "nothing"}.get(type(value), type(value).__name__)


#: an element index written straight after a name inside a flow collection (module docstring)
_FLOW_INDEX = re.compile(r"\[-?[0-9]+\]")
#: what ends a plain text inside a flow collection (besides the indicators themselves)
_FLOW_END = "\0 \t\r\n\x85\u2028\u2029,?[]{}#"


class LineLoader(yaml.SafeLoader):
    """SafeLoader producing LineDict/LineList, refusing duplicate keys, keys that are not text or
    numbers, nesting deeper than MAX_DEPTH and documents expanding to more than MAX_NODES nodes; inside a
    flow collection, ``name[3]`` is one text (module docstring)."""

    depth = 0

    def scan_plain(self):
        token = super().scan_plain()
        while self.flow_level and self.peek() == "[" and self.get_mark().index == token.end_mark.index:
            index = _FLOW_INDEX.match(self.prefix(24))
            if index is None:
                break
            self.forward(index.end())
            text, end = token.value + index.group(), self.get_mark()
            if self.peek() not in _FLOW_END and not (self.peek() == ":" and self.peek(1) in _FLOW_END):
                rest = super().scan_plain()
                text, end = text + rest.value, rest.end_mark
            token = yaml.tokens.ScalarToken(text, True, token.start_mark, end)
        return token

    def compose_node(self, parent, index):
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise ScenarioError(f"{self.name}:{mark.line + 1}: nested more than {MAX_DEPTH} levels deep")
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def get_single_data(self):
        node = self.get_single_node()
        if node is None:
            return None
        check_expansion(node, self.name)
        return self.construct_document(node)


def check_expansion(root: yaml.Node, filename: str) -> None:
    """Refuse a document whose aliases expand it past MAX_NODES nodes (a "billion laughs" file) or nest it
    deeper than MAX_DEPTH (an alias inside an alias inside ...), before anything is built from it."""
    measured: dict[int, tuple[int, int]] = {}  # node id -> (expanded size, depth below it)

    def measure(node) -> tuple[int, int]:
        key = id(node)
        if key in measured:
            return measured[key]
        measured[key] = (MAX_NODES + 1, MAX_DEPTH + 1)  # reached again while being measured: a cycle
        if isinstance(node, yaml.MappingNode):
            children = [measure(n) for pair in node.value for n in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = [measure(n) for n in node.value]
        else:
            children = []
        total = min(1 + sum(c[0] for c in children), MAX_NODES + 1)
        depth = 1 + max((c[1] for c in children), default=0)
        line = node.start_mark.line + 1
        if total > MAX_NODES:
            raise ScenarioError(f"{filename}:{line}: the document expands to more than {MAX_NODES} values "
                                "through its aliases (*name); write the values out")
        if depth > MAX_DEPTH:
            raise ScenarioError(f"{filename}:{line}: nested more than {MAX_DEPTH} levels deep (through aliases)")
        measured[key] = (total, depth)
        return total, depth

    measure(root)


def _construct_mapping(loader: LineLoader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    mapping = LineDict()
    mapping.line = node.start_mark.line + 1
    mapping.lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        line = key_node.start_mark.line + 1
        if not isinstance(key, (str, int, float, bool)) and key is not None:
            raise ScenarioError(f"{loader.name}:{line}: a key must be a name, given {type_name(key)} {show(key)}")
        if key in mapping:
            raise ScenarioError(f"{loader.name}:{line}: duplicate key {key!r} (first on line {mapping.lines[key]})")
        mapping[key] = loader.construct_object(value_node, deep=True)
        mapping.lines[key] = line
    return mapping


def _construct_sequence(loader: LineLoader, node: yaml.SequenceNode) -> LineList:
    sequence = LineList(loader.construct_object(child, deep=True) for child in node.value)
    sequence.line = node.start_mark.line + 1
    sequence.lines = [child.start_mark.line + 1 for child in node.value]
    return sequence


LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_yaml(text: str, filename: str = "<string>"):
    try:
        loader = LineLoader(text)
    except yaml.reader.ReaderError as exc:  # the reader checks every character first
        raise _reader_error(exc, text, filename) from None
    loader.name = filename
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else 0
        raise ScenarioError(f"{filename}:{line}: not valid YAML: {exc.problem}") from None
    except yaml.reader.ReaderError as exc:
        raise _reader_error(exc, text, filename) from None
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{filename}:1: not valid YAML: {show(str(exc))}") from None
    except RecursionError:
        raise ScenarioError(f"{filename}:1: nested too deeply to read") from None
    finally:
        loader.dispose()


def _reader_error(exc: yaml.reader.ReaderError, text: str, filename: str) -> ScenarioError:
    line = text.count("\n", 0, exc.position) + 1
    return ScenarioError(f"{filename}:{line}: not a text file: character {exc.character!r} ({exc.reason})")


def decode_scenario(data: bytes, path: str) -> str:
    """The text of a scenario file: UTF-8 (a UTF-8 byte-order mark is dropped); anything else refused."""
    if len(data) > MAX_BYTES:
        raise ScenarioError(f"{path}:1: larger than {MAX_BYTES // 2**20} MiB; a scenario is a short text file")
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise ScenarioError(f"{path}:1: encoded in UTF-16; save the scenario as UTF-8")
    if b"\x00" in data:
        line = data.count(b"\n", 0, data.index(b"\x00")) + 1
        raise ScenarioError(f"{path}:{line}: not a text file (it holds NUL bytes); a scenario is YAML text in UTF-8")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ScenarioError(f"{path}:{line}: not UTF-8 text (byte {data[exc.start]:#04x}); save the scenario "
                            "as UTF-8") from None
