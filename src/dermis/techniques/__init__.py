"""Rendering techniques, each in its own module with its own shaders, selected by name."""

from __future__ import annotations

from dermis.errors import DermisError


TECHNIQUE_MODULES = ("lambert", "tsd", "ssss", "preintegrated")


def _registry():
    """Technique classes by name: each module dermis.techniques.<name> holds a Technique subclass
    whose ``name`` is <name>."""
    from dermis.techniques.base import Technique

    reg = {}
    for mod in TECHNIQUE_MODULES:
        try:
            m = __import__(f"dermis.techniques.{mod}", fromlist=["_"])
        except ModuleNotFoundError as exc:
            if exc.name == f"dermis.techniques.{mod}":
                continue
            raise
        for obj in vars(m).values():
            if isinstance(obj, type) and issubclass(obj, Technique) and getattr(obj, "name", None) == mod:
                reg[mod] = obj
                break
    return reg


def technique_names() -> list[str]:
    return list(_registry())


def technique_class(name: str):
    reg = _registry()
    if name not in reg:
        raise DermisError(f"technique: unknown technique '{name}' (available: {', '.join(reg)})")
    return reg[name]
