"""The interactive viewer (``dermis view``) and turntable videos (``dermis turntable``).

- ``camera_controls``: orbit / zoom / pan and key-light dragging as plain math (no window).
- ``params``: the live parameters (technique, skin profile, material, light, environment,
  output) and how they are applied to a Scene; the skin-profile worker.
- ``present``: the GPU output transform (exposure, tone map, sRGB) that shows the linear image.
- ``gui``: Dear ImGui (imgui-bundle) drawn with moderngl, and the viewer's panel.
- ``script``: scripted input (a JSON list of per-frame actions) that drives the real window loop.
- ``app``: the window (GLFW, OpenGL 4.5 core) and its event loop, sharing its context with a
  :class:`dermis.renderer.Renderer`.
- ``turntable``: a spinning camera (and optionally light) written to .mp4, .gif or PNG frames.
"""
