"""Rendering techniques, each in its own module with its own shaders, selected by name."""

from __future__ import annotations

from dermis.errors import DermisError


def _registry():
    from dermis.techniques.lambert import Lambert

    reg = {"lambert": Lambert}
    for mod, cls in (("tsd", "TextureSpaceDiffusion"), ("ssss", "ScreenSpaceSSS"), ("preintegrated", "PreintegratedSkin")):
        try:
            m = __import__(f"dermis.techniques.{mod}", fromlist=[cls])
        except ModuleNotFoundError as exc:
            if exc.name == f"dermis.techniques.{mod}":
                continue
            raise
        reg[mod] = getattr(m, cls)
    return reg


def technique_names() -> list[str]:
    return list(_registry())


def technique_class(name: str):
    reg = _registry()
    if name not in reg:
        raise DermisError(f"--technique: unknown technique '{name}' (available: {', '.join(reg)})")
    return reg[name]
