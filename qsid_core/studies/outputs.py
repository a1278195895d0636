"""Files the engine and its front ends write: only a regular file or a new name, written whole or not at all."""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

from ..errors import OutputPathError
from ..validate import special_file_kind

__all__ = ["output_target", "replace_atomically"]


def _kind(mode: int) -> str:
    return special_file_kind(mode) or "not a regular file"


def output_target(path: str | os.PathLike[str]) -> Path:
    """The file that writing to ``path`` would replace: ``path`` itself, or the file a symbolic link points to.

    Raises
    ------
    OutputPathError
        ``path`` (or what a link at it points to) exists and is not a regular file: a directory, a device, a
        FIFO, a socket. Replacing it by a file would destroy it (a device node) or hang (a FIFO).
    """
    p = Path(path)
    target = Path(os.path.realpath(p)) if p.is_symlink() else p
    try:  # what a write through ``path`` reaches (``/dev/stdout`` into a pipe: a pipe, though no name is one)
        mode = os.stat(p).st_mode
    except FileNotFoundError:
        return target
    except OSError as exc:
        raise OutputPathError(f"output {str(path)!r}: cannot inspect it ({exc.strerror or exc})") from None
    if not stat.S_ISREG(mode):
        via = f" (a link to {str(target)!r})" if target != p else ""
        raise OutputPathError(
            f"output {str(path)!r}{via} is {_kind(mode)}, not a regular file; give a file name or a new name"
        )
    return target


def replace_atomically(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through a temporary file beside it and ``os.replace``.

    The file keeps its permission bits (a new one gets the umask's). A symbolic link at ``path`` keeps
    pointing where it did: the file it points to is replaced.

    Raises
    ------
    OutputPathError
        ``path`` exists and is not a regular file (see :func:`output_target`).
    """
    target = output_target(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        try:
            mode = os.stat(target).st_mode & 0o7777
        except OSError:
            mask = os.umask(0)
            os.umask(mask)
            mode = 0o666 & ~mask
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
