"""Counting live GPU objects on a moderngl context, to show that an interactive session leaks none.

moderngl 5 does not list a context's live objects (``ctx.objects`` only queues objects for its
deferred garbage collection), so :class:`GpuObjectTracker` wraps the context's factory methods
(``texture``, ``framebuffer``, ``program``, ...) on that one context object and remembers what
they return, weakly. An object counts as live until ``release()`` turns its handle into moderngl's
``InvalidObject``. Objects made before ``install`` are not counted. The tracker holds its
objects strongly: a wrapper dropped without ``release()`` still holds a GL object in the driver
(moderngl's default gc_mode frees nothing), so it stays counted, as the leak it is.
"""

from __future__ import annotations

from collections import Counter

FACTORIES = ("buffer", "texture", "texture3d", "texture_array", "texture_cube", "depth_texture", "depth_texture_cube",
             "framebuffer", "simple_framebuffer", "renderbuffer", "depth_renderbuffer", "program", "vertex_array",
             "simple_vertex_array", "query", "sampler", "scope", "compute_shader")


def _released(obj) -> bool:
    mglo = getattr(obj, "mglo", None)
    return mglo is None or type(mglo).__name__ == "InvalidObject"


class GpuObjectTracker:
    """``counts()`` -> {"texture": n, "framebuffer": n, ...}: objects made since ``install`` and
    not released."""

    PRUNE_EVERY = 512

    def __init__(self, ctx):
        self.ctx = ctx
        self._objects: dict[int, tuple[str, object]] = {}  # id -> (factory, object)
        self._installed = False

    def install(self) -> "GpuObjectTracker":
        if self._installed:
            return self
        for name in FACTORIES:
            original = getattr(self.ctx, name, None)
            if original is None:
                continue
            setattr(self.ctx, name, self._wrap(name, original))
        self._installed = True
        return self

    def _wrap(self, name, original):
        def factory(*args, **kwargs):
            obj = original(*args, **kwargs)
            self._objects[id(obj)] = (name, obj)  # factories calling factories: the outer name wins
            if len(self._objects) % self.PRUNE_EVERY == 0:
                self._prune()
            return obj

        factory.__wrapped__ = original
        factory.__name__ = name
        return factory

    def uninstall(self):
        for name in FACTORIES:
            wrapped = self.ctx.__dict__.get(name)
            if wrapped is not None:
                del self.ctx.__dict__[name]
        self._installed = False

    def _prune(self):
        self._objects = {k: (n, o) for k, (n, o) in self._objects.items() if not _released(o)}

    def counts(self) -> dict:
        self._prune()
        return dict(sorted(Counter(n for n, _ in self._objects.values()).items()))

    def total(self) -> int:
        return sum(self.counts().values())
