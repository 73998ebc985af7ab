"""Registry of model and assembly classes by name, so scenarios and ``flexshell models`` find them.

Register with the decorator::

    @register_model
    class PdAttitudeController(Model): ...

Third-party packages register the same way; they only need to be imported before a scenario is
built (``shell.registry.load_builtin()`` imports flexshell's own ``shell.models`` and
``shell.assemblies`` packages).
"""

from __future__ import annotations

import difflib
import importlib
import pkgutil

_REGISTRY: dict[str, type] = {}


class RegistryError(KeyError):
    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


def register_model(cls: type | None = None, *, name: str | None = None):
    """Class decorator adding a Model or Assembly subclass under ``name`` (default: class name)."""

    def decorate(klass: type) -> type:
        key = name or klass.__name__
        existing = _REGISTRY.get(key)
        if existing is not None and existing is not klass and (
                existing.__module__, existing.__qualname__) != (klass.__module__, klass.__qualname__):
            raise RegistryError(f"model type {key!r} is already registered by {existing.__module__}."
                                f"{existing.__qualname__}")
        _REGISTRY[key] = klass
        return klass

    return decorate(cls) if cls is not None else decorate


_LOADED: list = []


def load_builtin() -> None:
    """Import every module of shell.models and shell.assemblies so their decorators run (once)."""
    if _LOADED:
        return
    _LOADED.append(True)
    for package_name in ("shell.models", "shell.assemblies"):
        package = importlib.import_module(package_name)
        for info in pkgutil.walk_packages(package.__path__, prefix=package_name + "."):
            importlib.import_module(info.name)


def lookup(name: str) -> type:
    """The class registered as ``name``; the error suggests close names."""
    load_builtin()
    try:
        return _REGISTRY[name]
    except KeyError:
        close = difflib.get_close_matches(name, list(_REGISTRY), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        raise RegistryError(f"unknown model type {name!r}{hint} (see `flexshell models`)") from None


def registered() -> dict[str, type]:
    """All registered classes by name, sorted."""
    load_builtin()
    return dict(sorted(_REGISTRY.items()))
