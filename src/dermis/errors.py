"""User-facing errors.

Every error a user can cause (a bad file, a bad size, an unknown name) is raised as a
:class:`DermisError` whose message is ONE line naming the file or option and the problem.
The CLI prints it as ``dermis: error: <message>`` and exits with status 2, never a traceback.
"""

from __future__ import annotations


class DermisError(Exception):
    """An error caused by user input; its message is one line that says what and where."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


class GLUnavailableError(DermisError):
    """No OpenGL 4.5 core context could be created."""
