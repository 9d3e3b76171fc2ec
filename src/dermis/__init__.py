"""dermis: a physically based real-time renderer for human skin.

>>> import dermis
>>> scene = dermis.default_scene()                 # or dermis.load_scene("head.toml")
>>> img = dermis.render(scene, technique="tsd", size=(512, 512))   # float32 (H, W, 3), linear
"""

__version__ = "0.1.0"

from dermis.api import default_scene, load_scene, render  # noqa: E402
from dermis.errors import DermisError  # noqa: E402


def __getattr__(name):
    if name == "Renderer":
        from dermis.renderer import Renderer

        return Renderer
    raise AttributeError(name)


__all__ = ["load_scene", "default_scene", "render", "Renderer", "DermisError", "__version__"]
