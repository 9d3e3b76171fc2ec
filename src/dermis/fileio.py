"""Reading user files with one-line errors, and writing outputs all-or-nothing.

Inputs: only regular files are read (a FIFO would block forever, /dev/zero never ends), and every
OS error (EIO from /proc/self/mem, ENAMETOOLONG, EACCES, ...) becomes a DermisError naming the file.

Outputs (the policy, also in docs/scene-format.md): every requested output is written to a
temporary name in its destination folder and renamed over the target only when ALL of them were
written (:class:`OutputSet`); on any failure the temporaries are removed and no target changes.
An existing target must be a regular file: a directory, device, FIFO or socket is refused (so
``--exr /dev/null`` never replaces a device node). A target that is a symbolic link is written
THROUGH: the file the link points to is replaced (atomically, in the link target's folder) and
the link stays; a dangling link is refused.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from pathlib import Path

from dermis.errors import DermisError


def os_error_text(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def regular_file(path, what: str = "file") -> Path:
    """``path`` as a Path if it names an existing regular file (links followed), else DermisError."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise DermisError(f"{p}: {what} not found") from None
    except OSError as exc:
        raise DermisError(f"{p}: cannot open {what} ({os_error_text(exc)})") from None
    except ValueError:  # os.stat refuses a NUL byte: no file can have that name
        raise DermisError(f"{str(p).replace(chr(0), '<NUL>')}: {what} path contains a NUL byte") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a directory" if stat.S_ISDIR(st.st_mode) else "not a regular file"
        raise DermisError(f"{p}: {what} is {kind}")
    return p


def read_bytes(path, what: str = "file", max_bytes: int | None = None) -> bytes:
    """The bytes of a regular file; ``max_bytes`` refuses larger files before reading them."""
    p = regular_file(path, what)
    try:
        with open(p, "rb") as f:
            if max_bytes is not None:
                size = os.fstat(f.fileno()).st_size
                if size > max_bytes:
                    raise DermisError(f"{p}: {what} is {size} bytes, over the limit of {max_bytes}")
            return f.read()
    except OSError as exc:
        raise DermisError(f"{p}: cannot read {what} ({os_error_text(exc)})") from None


def read_text(path, what: str = "file") -> str:
    data = read_bytes(path, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise DermisError(f"{path}: {what} is not UTF-8 text") from None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def output_target(path) -> Path:
    """Where an output named ``path`` goes: checked, symbolic links resolved (see the policy)."""
    if path is None or str(path) == "":
        raise DermisError("output path is empty")
    p = Path(path)
    try:
        if p.is_symlink():
            target = Path(os.path.realpath(p))
            if not target.exists():
                raise DermisError(f"{p}: is a symbolic link to {target}, which does not exist; refused")
            p = target
        if p.exists() or p.is_symlink():
            st = p.stat()
            if stat.S_ISDIR(st.st_mode):
                raise DermisError(f"{path}: is a directory, not a file")
            if not stat.S_ISREG(st.st_mode):
                raise DermisError(f"{path}: exists and is not a regular file (device, FIFO or socket); refused")
    except OSError as exc:
        raise DermisError(f"{path}: cannot write ({os_error_text(exc)})") from None
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise DermisError(f"{path}: output folder {folder} does not exist")
    return p


class OutputSet:
    """Stage outputs under temporary names; ``commit`` renames them all, ``abort`` removes them.

    >>> with OutputSet() as outs:
    ...     outs.add("a.png", lambda tmp: write(tmp))   # written to .a.png.XXXX.part.png
    ...     outs.add_folder("dbg")                        # a folder of files, staged as a whole
    ...     outs.commit()                                  # nothing is renamed unless all succeeded
    """

    def __init__(self):
        self._files = []  # (tmp, target)
        self._folders = []  # (tmp dir, target dir)
        self._committed = False

    def reserve(self, path) -> Path:
        """Create the temporary file for ``path`` now (fails early on unwritable places)."""
        target = output_target(path)
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part" + target.suffix, dir=target.parent)
        except OSError as exc:
            raise DermisError(f"{path}: cannot write ({os_error_text(exc)})") from None
        os.close(fd)
        self._files.append((Path(tmp), target))
        return Path(tmp)

    def add(self, path, write_fn):
        """Write ``path`` through write_fn(temporary path) (reusing a reserved temporary)."""
        target = output_target(path)
        tmp = next((t for t, g in self._files if g == target), None) or self.reserve(path)
        try:
            write_fn(str(tmp))
        except DermisError:
            raise
        except OSError as exc:
            raise DermisError(f"{path}: cannot write ({os_error_text(exc)})") from None

    def folder(self, path) -> Path:
        """A staging folder for the output folder ``path``: files written into it appear in
        ``path`` on commit (``path`` is created then if missing)."""
        if path is None or str(path) == "":
            raise DermisError("output folder path is empty")
        p = Path(path)
        if p.exists() and not p.is_dir():
            raise DermisError(f"{path}: exists and is not a folder")
        parent = p.parent if str(p.parent) else Path(".")
        if not parent.is_dir():
            raise DermisError(f"{path}: its parent folder {parent} does not exist")
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".part", dir=parent))
        except OSError as exc:
            raise DermisError(f"{path}: cannot write ({os_error_text(exc)})") from None
        self._folders.append((tmp, p))
        return tmp

    def commit(self):
        mode = 0o666 & ~_umask()  # mkstemp makes 0600; outputs get the usual permissions
        files = {t.resolve() for _, t in self._files}
        for _, target in self._folders:  # everything that could fail is checked before any rename
            if target.resolve() in files or (target.exists() and not target.is_dir()):
                raise DermisError(f"{target}: the output folder is a file (or another output's name)")
        try:
            for tmp, target in self._files:
                os.chmod(tmp, mode)
                if target.exists() and not target.is_file():
                    raise DermisError(f"{target}: exists and is not a regular file; refused")
            for tmp, target in self._folders:
                for f in tmp.iterdir():
                    os.chmod(f, mode)
            for tmp, target in self._files:
                os.replace(tmp, target)
            for tmp, target in self._folders:
                if not target.exists():
                    os.chmod(tmp, 0o777 & ~_umask())
                    os.replace(tmp, target)
                else:
                    for f in sorted(tmp.iterdir()):
                        os.replace(f, target / f.name)
                    tmp.rmdir()
        except OSError as exc:
            raise DermisError(f"cannot move outputs into place ({os_error_text(exc)})") from None
        self._committed = True

    def abort(self):
        for tmp, _ in self._files:
            try:
                os.unlink(tmp)
            except OSError:
                pass
        for tmp, _ in self._folders:
            shutil.rmtree(tmp, ignore_errors=True)
        self._files, self._folders = [], []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if not self._committed:
            self.abort()


def atomic_write(path, write_fn) -> Path:
    """One output, all-or-nothing: write_fn(temporary path), then rename over ``path``."""
    with OutputSet() as outs:
        outs.add(path, write_fn)
        outs.commit()
    return output_target(path)
