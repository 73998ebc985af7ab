"""numba's on-disk cache for flexshell: one entry per compiled function, keyed on everything its machine code
depends on, and the clock of compilations that ``flexshell run`` and Monte Carlo report.

numba's own cache (``cache=True``) keys a function on its own file: after an edit of ``dynamics/kernels/kinematics.py`` a
cached caller in another file (the engine entry points, a model kernel) keeps the callee's old machine code, which
numba compiled into it, and runs outdated physics. :func:`configure` makes ``enable_caching`` of numba's
dispatchers (``@njit(cache=True)``, ``@cfunc(cache=True)``) install a :class:`DependencyCache` instead of numba's
``FunctionCache``, before any kernel module is imported. Its entry of a function for one signature is the file
``<cache>/<module>/<qualname>-<signature>-<key>.nbc`` where ``key`` is a sha256 of

* the function's *unit*, the functions numba may compile into its code, resolved from the objects in memory (what
  numba compiles, not what the files say): the function itself and, transitively, every numba function (plain or
  ``inline="always"``), ``@overload`` implementation, ``@intrinsic`` definition and plain Python function of a
  non-library module that it reads from its globals (attribute chains such as ``K.forward_dynamics`` followed through
  modules and classes), its closure cells and default arguments, plus the ``@overload_method``,
  ``@overload_attribute`` and library-function ``@overload`` implementations of non-library modules (reachable from
  any function: typed on numba types or numpy's functions); each function by its
  bytecode, constants, names, options (``fastmath``, ``inline``, ...) and ``locals``, not its line numbers, so an edit
  elsewhere in its file leaves it cached;
* the *values* it reads at compile time: numba freezes a global int, float, tuple, array, enum member or numba type
  into the machine code, so a constant changed in another module gives every reader a new key;
* the function's compiler options (``fastmath``, ``boundscheck``, ``locals``, pipeline), its signature (a named
  tuple type with its class's fields), the target CPU (numba's codegen magic tuple), the
  Python, numba, llvmlite and numpy versions and numba's code-generation settings (``NUMBA_OPT``, boundscheck, ...).

A changed callee therefore changes the key of every caller, and only of those: editing one model file recompiles
that model's kernels, not the engine nor the compiled loop (which calls kernels through function pointers and so
does not contain them). Cycles (mutual recursion) are hashed as one strongly connected component (Tarjan's
algorithm). Each function's digest is computed once per process and kept with the bindings it read (globals,
attributes, cells, defaults, overloads); a binding rebound since (a test's monkeypatch, ``Dispatcher.recompile``
after the user changed a global) makes the digest be computed again. An array changed in place after its readers
were keyed is not seen (numba does not see it either in code it compiled). Library modules (the standard library,
numba, numpy, llvmlite, scipy) are not followed; their versions are in the key. numba's low-level extension API
(``lower_builtin``, ``type_callable``, ``typeof_impl``, data models) is not followed either; flexshell does not use
it (a test checks).

Entries are content-addressed: the same key always holds equivalent machine code, so processes, checkouts and
worktrees of flexshell share one directory without an index to race on (a file is written to a temporary name and
renamed). The directory is ``$NUMBA_CACHE_DIR`` when the user sets it, else ``~/.cache/flexshell/kernels``
(``$XDG_CACHE_HOME`` honoured; a temporary directory, with a warning, when neither is writable). Entries unused
(neither loaded nor written) for a week are removed, and of one function's entries for one signature only the
:data:`KEEP` most recently used; a removed entry costs a compilation, never a wrong result.
"""

from __future__ import annotations

import dis
import enum
import hashlib
import inspect
import os
import pickle
import sys
import tempfile
import time
import types as pytypes
import uuid
import warnings
from pathlib import Path

from numba.core.caching import _Cache

#: bump when the composition of the key changes (old entries then are never loaded, and age out)
SCHEME = 1
#: entries of one function and signature kept at pruning, most recently used first (versions in use by several
#: checkouts or branches)
KEEP = 8
STALE_AFTER_S = 7 * 24 * 3600.0
#: pruning runs at most this often (a stamp file in the directory)
PRUNE_EVERY_S = 24 * 3600.0
#: top-level packages whose objects are identified by name and version, not followed
LIBRARIES = frozenset({"numba", "numpy", "llvmlite", "scipy", "builtins"}) | frozenset(sys.stdlib_module_names)

_DIRECTORY: list[Path | None] = [None]


def configure() -> str | None:
    """Install :class:`DependencyCache` as numba's function cache and choose its directory (see the module
    docstring); returns the directory, or None when no directory is writable (then nothing is cached)."""
    import numba
    from numba.core.ccallback import CFunc
    from numba.core.dispatcher import Dispatcher

    for owner in (Dispatcher, CFunc):
        if not callable(getattr(owner, "enable_caching", None)):  # numba moved it: refuse rather than risk stale code
            raise RuntimeError(f"flexshell: {owner.__qualname__}.enable_caching not found in numba "
                               f"{numba.__version__}: dynamics/compile_cache.py cannot install its cache")
        owner.enable_caching = _enable_caching
    directory = _usable_directory()
    _DIRECTORY[0] = directory
    if directory is None:
        return None
    numba.config.CACHE_DIR = str(directory)  # numba's other caches, and child processes through NUMBA_CACHE_DIR
    _prune(directory)
    return str(directory)


def cache_directory() -> Path | None:
    """The directory :func:`configure` chose."""
    return _DIRECTORY[0]


def _usable_directory() -> Path | None:
    chosen = os.environ.get("NUMBA_CACHE_DIR")
    home = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    candidates = [Path(chosen)] if chosen else [home / "flexshell" / "kernels"]
    candidates.append(Path(tempfile.gettempdir()) / f"flexshell-{os.getuid() if hasattr(os, 'getuid') else 0}"
                      / "kernels")
    refused = []
    for directory in candidates:
        try:
            directory.mkdir(parents=True, exist_ok=True)
            tempfile.TemporaryFile(dir=directory).close()
        except OSError as exc:
            refused.append(f"{directory} ({exc.strerror or exc})")
            continue
        if refused:
            warnings.warn(f"flexshell: cannot write the kernel cache {refused[0]}; caching in {directory}")
        return directory
    warnings.warn(f"flexshell: no writable kernel cache ({'; '.join(refused)}): every process compiles its kernels")
    return None


def _prune(directory: Path) -> None:
    """Remove entries unused for a week and all but the KEEP most recent of each function and signature (at most
    daily)."""
    stamp = directory / ".pruned"
    now = time.time()
    try:
        if now - stamp.stat().st_mtime < PRUNE_EVERY_S:
            return
    except OSError:
        pass
    try:
        stamp.touch()
        groups: dict[tuple[Path, str], list[tuple[float, Path]]] = {}
        for entry in directory.glob("*/*.nbc"):
            function_and_signature = entry.name.rsplit("-", 1)[0]
            groups.setdefault((entry.parent, function_and_signature), []).append((entry.stat().st_mtime, entry))
        for entries in groups.values():
            entries.sort(reverse=True)
            for rank, (used, entry) in enumerate(entries):
                if rank >= KEEP or now - used > STALE_AFTER_S:
                    entry.unlink(missing_ok=True)
    except OSError:  # another process pruning at the same time, or a read-only directory
        pass


# --------------------------------------------------------------------------------------------------------------
# the cache numba's dispatchers use
# --------------------------------------------------------------------------------------------------------------

def _enable_caching(self) -> None:
    """``enable_caching`` of numba's ``Dispatcher`` and ``CFunc`` once :func:`configure` ran."""
    self._cache = DependencyCache(self)


class DependencyCache(_Cache):
    """numba's cache interface (``load_overload``, ``save_overload``, ...) over content-addressed entry files whose
    name carries :func:`entry_name` (see the module docstring). ``owner``: the numba ``Dispatcher`` or ``CFunc``."""

    def __init__(self, owner):
        self._py_func = owner.py_func if hasattr(owner, "py_func") else owner._pyfunc
        compiler = owner._compiler
        self._options = (f"{sorted((k, repr(v)) for k, v in compiler.targetoptions.items())}"
                         f"{sorted((k, str(v)) for k, v in (compiler.locals or {}).items())}"
                         f"{_identity(compiler.pipeline_class)}")
        self._enabled = True
        self._module = getattr(self._py_func, "__module__", None) or "__unknown__"
        self._stem = getattr(self._py_func, "__qualname__", self._py_func.__name__).replace("<", "").replace(">", "")

    def __repr__(self) -> str:
        return f"<DependencyCache {self._module}.{self._stem}>"

    @property
    def cache_path(self):
        directory = _DIRECTORY[0]
        return None if directory is None else str(directory / self._module)

    def enable(self) -> None:
        self._enabled = True

    def disable(self) -> None:
        self._enabled = False

    def flush(self) -> None:
        """Forget every digest (``Dispatcher.recompile``): keys are computed again from the objects in memory.
        Entries on disk stay valid for their own keys."""
        _forget()

    def entry_path(self, sig, codegen) -> Path | None:
        """The entry file of this function compiled for ``sig`` with ``codegen`` (None: no cache directory)."""
        directory = _DIRECTORY[0]
        if directory is None:
            return None
        return directory / self._module / f"{self._stem}-{entry_name(self._py_func, self._options, sig, codegen)}.nbc"

    def load_overload(self, sig, target_context):
        if not self._enabled:
            return None
        target_context.refresh()
        path = self.entry_path(sig, target_context.codegen())
        if path is None:
            return None
        try:
            payload = pickle.loads(path.read_bytes())
        except FileNotFoundError:
            return None
        except Exception:  # a truncated or foreign file: compile again (and overwrite it)
            return None
        try:
            os.utime(path)  # most recently used, for pruning
        except OSError:
            pass
        from numba.core.compiler import CompileResult

        return CompileResult._rebuild(target_context, *payload)

    def save_overload(self, sig, cres) -> None:
        if not self._enabled or not self._cachable(cres):
            return
        path = self.entry_path(sig, cres.codegen)
        if path is None:
            return
        from numba.core.serialize import dumps

        data = dumps(cres._reduce())
        temporary = path.with_name(f"{path.name}.tmp.{uuid.uuid4().hex[:16]}")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            temporary.write_bytes(data)
            os.replace(temporary, path)
        except OSError:  # a full or read-only disk: the function stays compiled in this process
            temporary.unlink(missing_ok=True)

    def _cachable(self, cres) -> bool:
        """numba's own refusals (``CompileResultCacheImpl.check_cachable``), with its warning."""
        from numba.core.errors import NumbaWarning

        if any(not lifted.can_cache for lifted in cres.lifted):
            reason = "as it uses lifted code"
        elif cres.library.has_dynamic_globals:
            reason = "as it uses dynamic globals (such as ctypes pointers and large global arrays)"
        else:
            return True
        warnings.warn(f'Cannot cache compiled function "{cres.fndesc.qualname.split(".")[-1]}" {reason}', NumbaWarning)
        return False


# --------------------------------------------------------------------------------------------------------------
# keys
# --------------------------------------------------------------------------------------------------------------

def entry_name(py_func, options: str, sig, codegen) -> str:
    """``<signature digest>-<key>`` (8 and 24 hex digits of sha256) naming the entry of ``py_func`` compiled with
    compiler ``options`` for ``sig`` by ``codegen``; the key covers all of it (see the module docstring)."""
    from numba.core import sigutils

    args, return_type = sigutils.normalize_signature(sig)
    signature = "\0".join(_type_token(argument) for argument in (*args, return_type))
    digest = hashlib.sha256(_environment_key())
    for part in (options, signature, repr(codegen.magic_tuple()), unit_key(py_func)):
        digest.update(part.encode())
        digest.update(b"\0")
    return f"{hashlib.sha256(signature.encode()).hexdigest()[:8]}-{digest.hexdigest()[:24]}"


def unit_key(function) -> str:
    """sha256 of ``function``'s unit (it and everything numba may compile into it, with the values they read)."""
    node = _Node.of(function)
    if node is None:  # a function of numba or numpy themselves: their versions are in the key
        return hashlib.sha256(_library_token(function).encode()).hexdigest()
    _revalidate(node)
    _hash_components(node)
    return hashlib.sha256(f"{node.identity}\0{_MERKLE[node.key]}".encode()).hexdigest()


def unit_members(function) -> list[str]:
    """The functions of ``function``'s unit (module.qualname, sorted): what an edit must touch to recompile it."""
    node = _Node.of(function)
    if node is None:
        return []
    unit_key(function)
    seen, stack = {}, [node]
    while stack:
        member = stack.pop()
        if member.key not in seen:
            seen[member.key] = member.identity
            stack.extend(member.edges)
    return sorted(seen.values())


_ENVIRONMENT: list[bytes] = []


def _environment_key() -> bytes:
    if not _ENVIRONMENT:
        import llvmlite
        import numba
        import numpy
        from numba.core import config

        settings = {name: repr(getattr(config, name, None)) for name in (
            "OPT", "BOUNDSCHECK", "DEBUGINFO_DEFAULT", "LOOP_VECTORIZE", "SLP_VECTORIZE", "ENABLE_AVX",
            "CPU_NAME", "CPU_FEATURES", "FASTMATH", "DISABLE_JIT")}
        _ENVIRONMENT.append(repr((SCHEME, sys.version, sys.implementation.cache_tag, numba.__version__,
                                  llvmlite.__version__, numpy.__version__, sorted(settings.items()))).encode())
    return _ENVIRONMENT[0]


def _type_token(numba_type) -> str:
    """A numba type as text, with the fields of the named-tuple classes inside it (numba names a named tuple type
    by its class's name and member types only)."""
    from numba.core import types

    text = str(numba_type)
    extra = []

    def visit(t):
        if isinstance(t, types.BaseNamedTuple):
            cls = t.instance_class
            extra.append(f"{_identity(cls)}{tuple(getattr(cls, '_fields', ()))}")
        if isinstance(t, types.BaseTuple):
            for member in t.types:
                visit(member)

    visit(numba_type)
    return text + "".join(extra)


# the graph: nodes are functions (numba dispatchers, plain functions, intrinsics); a node's local digest covers its
# own code and the values it reads, naming the nodes it reads by identity; _MERKLE adds the nodes it reaches.

_LOCAL: dict[int, "_Node"] = {}   # id(object) -> node (the node keeps the object alive, so ids stay unique)
_MERKLE: dict[int, str] = {}      # id(object) -> hash of its strongly connected component and all it reaches
_CODE: dict[int, tuple] = {}      # id(code object) -> (code, digest)
_OVERLOADS: list = [None, {}, []]  # registry size seen, id(function) -> implementations, method/attribute impls


def _forget() -> None:
    _LOCAL.clear()
    _MERKLE.clear()
    _OVERLOADS[0] = None


def _top_package(obj) -> str:
    module = getattr(obj, "__module__", None)
    if not isinstance(module, str):
        module = type(obj).__module__
    return module.split(".")[0]


def _is_library(obj) -> bool:
    return _top_package(obj) in LIBRARIES


def _identity(obj) -> str:
    module = getattr(obj, "__module__", None)
    name = getattr(obj, "__qualname__", None) or getattr(obj, "__name__", None) or type(obj).__qualname__
    return f"{module}.{name}"


def _library_token(obj) -> str:
    package = _top_package(obj)
    version = getattr(sys.modules.get(package), "__version__", "")
    return f"library:{_identity(obj)}@{version}"


class _Node:
    """One function of the graph: its local digest, the nodes it reads, and the bindings its digest read (a global,
    attribute, cell or default rebound since makes the digest stale: :func:`_revalidate`)."""

    __slots__ = ("obj", "key", "identity", "local", "edges", "bindings")

    def __init__(self, obj, identity):
        self.obj, self.key, self.identity = obj, id(obj), identity
        self.local: str | None = None
        self.edges: list[_Node] = []
        self.bindings: list[tuple] = []

    @staticmethod
    def of(obj) -> "_Node | None":
        """The node of ``obj``, or None when ``obj`` is not a followed function."""
        node = _LOCAL.get(id(obj))
        if node is not None and node.obj is obj:
            return node
        from numba.core.dispatcher import Dispatcher
        from numba.core.extending import _Intrinsic

        if isinstance(obj, Dispatcher):
            function = obj.py_func
        elif isinstance(obj, _Intrinsic):
            function = obj._defn
        elif isinstance(obj, pytypes.FunctionType):
            function = obj
        else:
            return None
        if _is_library(function):
            return None
        node = _Node(obj, _identity(function))
        _LOCAL[node.key] = node
        return node

    def digest(self) -> str:
        if self.local is None:
            self.edges, self.bindings = [], []
            self.local = self._local_digest()
        return self.local

    def holds(self) -> bool:
        """Whether every binding its digest read still holds the same object."""
        return all(_bound(holder, name) == value if holder is _OVERLOADS_OF else _bound(holder, name) is value
                   for holder, name, value in self.bindings)

    def _local_digest(self) -> str:
        from numba.core.dispatcher import Dispatcher
        from numba.core.extending import _Intrinsic

        obj, parts = self.obj, [self.identity]
        if isinstance(obj, Dispatcher):
            parts.append(f"dispatcher:{sorted((k, repr(v)) for k, v in obj.targetoptions.items())}"
                         f":{sorted((k, str(v)) for k, v in (obj.locals or {}).items())}")
            function = obj.py_func
        elif isinstance(obj, _Intrinsic):
            parts.append(f"intrinsic:{sorted((k, repr(v)) for k, v in obj._ctor_kwargs.items())}"
                         f":{obj._prefer_literal}")
            function = obj._defn
        else:
            function = obj
        parts.append(_code_digest(function.__code__))
        for name in ("__defaults__", "__kwdefaults__"):
            value = getattr(function, name)
            self.bindings.append((function, name, value))
            parts.append(f"{name}=" + _token(value, self.edges))
        closure = _closure(function)
        for name, cell in closure.items():
            value = _bound(cell, _CELL)
            self.bindings.append((cell, _CELL, value))
            parts.append(f"cell {name}=" + ("<empty>" if value is _MISSING else _token(value, self.edges)))
        for dotted, (holder, name, value) in sorted(_references(function, closure).items()):
            self.bindings.append((holder, name, value))
            parts.append(f"{dotted}=" + _token(value, self.edges))
        function_overloads, other_overloads = _overloads()
        implementations = tuple(function_overloads.get(id(obj), ())) + tuple(other_overloads)
        self.bindings.append((_OVERLOADS_OF, obj, implementations))
        for implementation, options in implementations:
            parts.append(f"overload {options}=" + _token(implementation, self.edges))
        return hashlib.sha256("\n".join(parts).encode()).hexdigest()


_CELL = "cell_contents"
_OVERLOADS_OF = object()  # holder of a binding: the @overload implementations of a function


def _bound(holder, name):
    """What ``holder`` binds to ``name`` now (_MISSING if nothing): a namespace dict, a cell, the registry of
    overloads, or an object's attribute."""
    if isinstance(holder, dict):
        return holder.get(name, _MISSING)
    if holder is _OVERLOADS_OF:
        function_overloads, other_overloads = _overloads()
        return tuple(function_overloads.get(id(name), ())) + tuple(other_overloads)
    if isinstance(holder, pytypes.CellType):
        try:
            return holder.cell_contents
        except ValueError:  # an empty cell
            return _MISSING
    return getattr(holder, name, _MISSING)


def _closure(function) -> dict:
    return dict(zip(function.__code__.co_freevars, function.__closure__ or ()))


_MISSING = object()


def _references(function, closure) -> dict:
    """dotted name -> (holder, name, value) of every global, builtin and closure name ``function``'s code (nested
    code included) loads, attribute chains through modules and classes followed to their end
    (``K.forward_dynamics``: the holder is module K)."""
    top = function.__code__
    namespace = function.__globals__
    builtins = namespace.get("__builtins__", __builtins__)
    builtins = builtins if isinstance(builtins, dict) else vars(builtins)
    found = {}
    for code in _codes(top):
        loads = _loads(code)
        for i, (kind, name) in enumerate(loads):
            if kind == "global":
                holder = namespace if name in namespace else builtins
                binding = (holder, name, _bound(holder, name))
            elif kind == "cell" and name in closure and (code is top or name not in top.co_cellvars):
                binding = (closure[name], _CELL, _bound(closure[name], _CELL))
            else:
                continue
            dotted = name
            j = i + 1
            while (j < len(loads) and loads[j][0] == "attribute"
                   and isinstance(binding[2], (pytypes.ModuleType, type))):
                holder = binding[2]
                binding = (holder, loads[j][1], _bound(holder, loads[j][1]))
                dotted += "." + loads[j][1]
                j += 1
            found[dotted] = binding
    return found


_OPCODES = dis.opmap
_EXTENDED_ARG, _CACHE = _OPCODES["EXTENDED_ARG"], _OPCODES.get("CACHE", -1)
_LOAD_GLOBAL, _LOAD_NAME, _LOAD_ATTR = _OPCODES["LOAD_GLOBAL"], _OPCODES["LOAD_NAME"], _OPCODES["LOAD_ATTR"]
_LOAD_METHOD = _OPCODES.get("LOAD_METHOD", -1)
_LOAD_CELLS = {_OPCODES[name] for name in ("LOAD_DEREF", "LOAD_CLASSDEREF") if name in _OPCODES}
_DECODER: list = []  # [True] when _decode agrees with dis on this interpreter


def _loads(code) -> list:
    """The instructions of ``code`` as (kind, name): kind "global" (LOAD_GLOBAL, LOAD_NAME), "attribute"
    (LOAD_ATTR, LOAD_METHOD), "cell" (LOAD_DEREF), or (None, None) for any other instruction; EXTENDED_ARG and
    inline caches left out. Decoded directly from the bytecode (dis.get_instructions costs ~8 ms per engine
    function), after checking once per process that the direct decoding agrees with dis here."""
    if not _DECODER:
        _DECODER.append(all(_decode(c) == _disassemble(c) for f in (_references, _token, _hash_components)
                            for c in _codes(f.__code__)))
    return _decode(code) if _DECODER[0] else _disassemble(code)


def _decode(code) -> list:
    names, raw = code.co_names, code.co_code
    wide_global, wide_attribute = sys.version_info >= (3, 11), sys.version_info >= (3, 12)
    cells = code.co_cellvars + code.co_freevars
    out, extended = [], 0
    for i in range(0, len(raw), 2):
        op, arg = raw[i], raw[i + 1] | extended
        if op == _EXTENDED_ARG:
            extended = arg << 8
            continue
        extended = 0
        if op == _LOAD_GLOBAL:
            out.append(("global", names[arg >> 1] if wide_global else names[arg]))
        elif op == _LOAD_NAME:
            out.append(("global", names[arg]))
        elif op == _LOAD_ATTR:
            out.append(("attribute", names[arg >> 1] if wide_attribute else names[arg]))
        elif op == _LOAD_METHOD:
            out.append(("attribute", names[arg]))
        elif op in _LOAD_CELLS:
            out.append(("cell", code._varname_from_oparg(arg) if wide_global else cells[arg]))
        elif op != _CACHE:
            out.append((None, None))
    return out


def _disassemble(code) -> list:
    kinds = {"LOAD_GLOBAL": "global", "LOAD_NAME": "global", "LOAD_ATTR": "attribute", "LOAD_METHOD": "attribute",
             "LOAD_DEREF": "cell", "LOAD_CLASSDEREF": "cell"}
    return [(kinds[i.opname], i.argval) if i.opname in kinds else (None, None)
            for i in dis.get_instructions(code) if i.opname != "EXTENDED_ARG"]


def _codes(code):
    yield code
    for constant in code.co_consts:
        if isinstance(constant, pytypes.CodeType):
            yield from _codes(constant)


def _code_digest(code) -> str:
    """sha256 of a code object without its file name and line numbers (nested code objects included)."""
    cached = _CODE.get(id(code))
    if cached is not None and cached[0] is code:
        return cached[1]
    parts = [code.co_name, repr((code.co_argcount, code.co_posonlyargcount, code.co_kwonlyargcount, code.co_flags)),
             code.co_code.hex(), repr(code.co_names), repr(code.co_varnames), repr(code.co_freevars),
             repr(code.co_cellvars)]
    for constant in code.co_consts:
        parts.append(_code_digest(constant) if isinstance(constant, pytypes.CodeType) else _constant_text(constant))
    digest = hashlib.sha256("\n".join(parts).encode()).hexdigest()
    _CODE[id(code)] = (code, digest)
    return digest


def _constant_text(constant) -> str:
    if isinstance(constant, frozenset):  # its iteration order varies with the string hash seed
        return "frozenset{" + ",".join(sorted(_constant_text(c) for c in constant)) + "}"
    if isinstance(constant, tuple):
        return "(" + ",".join(_constant_text(c) for c in constant) + ")"
    return f"{type(constant).__name__}:{constant!r}"


def _token(value, edges: list, depth: int = 0) -> str:
    """``value`` as text for a digest: a followed function by its identity (and an edge to it), a constant by its
    value, a library object by name and version."""
    if depth > 20:
        return f"<deep {type(value).__qualname__}>"
    node = _Node.of(value)
    if node is not None:
        edges.append(node)
        return "node:" + node.identity
    if value is _MISSING:
        return "<missing>"
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes)):
        return f"{type(value).__name__}:{value!r}"
    import numpy as np
    from numba.core import types

    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value)
        body = hashlib.sha256(data.tobytes()).hexdigest() if data.dtype != object else repr(data.tolist())
        return f"array:{data.dtype.str}:{data.dtype.descr}:{data.shape}:{body}"
    if isinstance(value, (np.generic, np.dtype)):
        return f"numpy:{value.dtype.str if isinstance(value, np.generic) else ''}:{value!r}"
    if isinstance(value, enum.Enum):
        return f"enum:{_identity(type(value))}.{value.name}=" + _token(value.value, edges, depth + 1)
    if isinstance(value, (tuple, list)):
        fields = getattr(type(value), "_fields", None)
        head = f"{_identity(type(value))}{tuple(fields)}" if fields is not None else type(value).__name__
        return head + "(" + ",".join(_token(v, edges, depth + 1) for v in value) + ")"
    if isinstance(value, dict):
        return "dict{" + ",".join(f"{_token(k, edges, depth + 1)}:{_token(v, edges, depth + 1)}"
                                  for k, v in sorted(value.items(), key=lambda kv: repr(kv[0]))) + "}"
    if isinstance(value, types.Type):
        return "numba-type:" + _type_token(value)
    if isinstance(value, pytypes.ModuleType):
        return "module:" + value.__name__
    if _is_library(value):
        return _library_token(value)
    if isinstance(value, type):
        return _class_token(value, edges, depth)
    text = repr(value)
    if " at 0x" not in text:
        return f"object:{_identity(type(value))}:{text}"
    try:
        return f"object:{_identity(type(value))}:" + hashlib.sha256(pickle.dumps(value)).hexdigest()
    except Exception:
        return f"object:{_identity(type(value))}"


def _class_token(cls, edges, depth) -> str:
    """A class of a followed module: its identity, bases, named-tuple fields and defaults, and the functions and
    constants it defines (numba reads a class when it constructs a named tuple or an overload inspects a type)."""
    parts = [f"class:{_identity(cls)}", ",".join(_identity(base) for base in cls.__bases__),
             repr(getattr(cls, "_fields", None))]
    for name, member in sorted(vars(cls).items()):
        if name.startswith("__") or name in ("_fields", "_field_defaults") or isinstance(member, property):
            continue
        if isinstance(member, (staticmethod, classmethod)):
            member = member.__func__
        parts.append(f"{name}=" + _token(member, edges, depth + 1))
    parts.append(_token(getattr(cls, "_field_defaults", None), edges, depth + 1))
    return "|".join(parts)


def _overloads():
    """(id(function) -> its ``@overload`` implementations, the other implementations: ``@overload_method``,
    ``@overload_attribute``, ``@overload`` of a library function) of followed modules, each as (implementation, its
    options as text), from numba's typing registry (rescanned when it grows)."""
    from numba.core.typing.templates import builtin_registry

    size = len(builtin_registry.functions) + len(builtin_registry.attributes)
    if _OVERLOADS[0] != size:
        by_function: dict[int, list] = {}
        methods = []
        for on_functions, templates in ((True, builtin_registry.functions), (False, builtin_registry.attributes)):
            for template in templates:
                implementation = getattr(template, "_overload_func", None)
                if implementation is None or _is_library(implementation):
                    continue
                options = (f"{sorted((k, repr(v)) for k, v in getattr(template, '_jit_options', {}).items())}"
                           f":{getattr(getattr(template, '_inline', None), 'value', None)!r}"
                           f":{getattr(template, 'prefer_literal', None)!r}:{getattr(template, '_attr', None)!r}")
                key = getattr(template, "key", None)
                if on_functions and callable(key) and not inspect.isclass(key) and not _is_library(key):
                    by_function.setdefault(id(key), []).append((implementation, options))
                else:  # typed on a numba type, or overloading a library function (numpy's): read by any function
                    methods.append((implementation, options))
        _OVERLOADS[:] = [size, by_function, methods]
    return _OVERLOADS[1], _OVERLOADS[2]


def _revalidate(root: _Node) -> None:
    """Forget the digest of every node reachable from ``root`` whose bindings changed since it was hashed (a module
    constant or a global rebound at run time, ``Dispatcher.recompile``), and then every component hash."""
    seen, stack, stale = set(), [root], False
    while stack:
        node = stack.pop()
        if node.key in seen:
            continue
        seen.add(node.key)
        if node.local is not None and not node.holds():
            node.local = None
            stale = True
        stack.extend(node.edges)
    if stale:
        _MERKLE.clear()


def _hash_components(root: _Node) -> None:
    """_MERKLE of ``root`` and of every node it reaches: Tarjan's strongly connected components; a component's hash
    covers its members' local digests, which member reads which node, and the hashes of the components it reads."""
    if root.key in _MERKLE:
        return
    index: dict[int, int] = {}
    low: dict[int, int] = {}
    stack: list[_Node] = []
    on_stack: set[int] = set()
    counter = [0]

    def connect(node: _Node) -> None:
        index[node.key] = low[node.key] = counter[0]
        counter[0] += 1
        stack.append(node)
        on_stack.add(node.key)
        node.digest()
        for target in node.edges:
            if target.key in _MERKLE:
                continue
            if target.key not in index:
                connect(target)
                low[node.key] = min(low[node.key], low[target.key])
            elif target.key in on_stack:
                low[node.key] = min(low[node.key], index[target.key])
        if low[node.key] == index[node.key]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member.key)
                component.append(member)
                if member is node:
                    break
            keys = {member.key for member in component}
            lines = []
            for member in component:
                reads = [f"{target.identity}:{'inside' if target.key in keys else _MERKLE[target.key]}"
                         for target in member.edges]
                lines.append(member.digest() + ">" + ",".join(reads))
            merkle = hashlib.sha256("\n".join(sorted(lines)).encode()).hexdigest()
            for member in component:
                _MERKLE[member.key] = merkle

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10000))
    try:
        connect(root)
    finally:
        sys.setrecursionlimit(limit)


# --------------------------------------------------------------------------------------------------------------
# compile clock
# --------------------------------------------------------------------------------------------------------------

class CompileClock:
    """numba's compilations in this process, followed through its ``numba:compile`` event (raised when a kernel is
    compiled, not when it is loaded from the on-disk cache): ``seconds`` spent compiling (a compilation and the
    callees it compiles counted once), and ``on_start(dispatcher)`` called as each compilation, outer or nested,
    starts. Listens from :meth:`start` to :meth:`stop` (`flexshell run`'s compile notice, the Monte Carlo runs'
    compile counter and timeout)."""

    def __init__(self, on_start=None):
        self.seconds = 0.0
        self._on_start, self._depth, self._started, self._listener = on_start, 0, 0.0, None

    @property
    def running(self) -> bool:
        return self._listener is not None

    @property
    def depth(self) -> int:
        """Compilations under way (1 inside ``on_start`` of an outer one: numba compiles callees nested)."""
        return self._depth

    def start(self) -> "CompileClock":
        from numba.core import event

        clock = self

        class _Listener(event.Listener):
            def on_start(self, ev) -> None:
                if clock._depth == 0:
                    clock._started = time.perf_counter()
                clock._depth += 1
                if clock._on_start is not None:
                    clock._on_start((ev.data or {}).get("dispatcher"))

            def on_end(self, ev) -> None:
                clock._depth -= 1
                if clock._depth == 0:
                    clock.seconds += time.perf_counter() - clock._started

        self._listener = _Listener()
        event.register("numba:compile", self._listener)
        return self

    def stop(self) -> None:
        if self._listener is not None:
            from numba.core import event

            event.unregister("numba:compile", self._listener)
            self._listener = None
