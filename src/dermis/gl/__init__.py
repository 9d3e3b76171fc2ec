"""OpenGL plumbing: headless context creation and the GLSL loader with #include."""

from dermis.gl.context import create_context, gl_info
from dermis.gl.shaders import load_shader_source, program

__all__ = ["create_context", "gl_info", "load_shader_source", "program"]
