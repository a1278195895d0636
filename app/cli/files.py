"""The files a ``qsid`` command reads and writes: an output file checked before any work (a file name, not a
folder, not an input, a regular file or a new name where a file can be created now), the inputs it must never
overwrite, and an atomic write whose late failure keeps the output in the temporary folder."""

from __future__ import annotations

import argparse
import contextlib
import os
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from app.stop import check_stopped

from .parser import UsageError

if TYPE_CHECKING:
    from .runner import Reporter

__all__ = ["check_writable", "input_files", "out_file", "save_output", "write_text"]


def check_writable(directory: Path, flag: str = "--out") -> None:
    """A :class:`UsageError` naming ``flag`` unless ``directory`` is writable."""
    if not os.access(directory, os.W_OK):
        raise UsageError(f"argument {flag}: cannot write into {str(directory)!r} (permission denied)")


def input_files(args: argparse.Namespace) -> list[Path]:
    """Files the run reads (an ``--out`` must never be one of them)."""
    p = Path(args.system)
    return [p] if getattr(args, "a_text", None) is None and p.is_file() else []


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def _probe(folder: Path, flag: str) -> None:
    """Create and remove a temporary file in ``folder`` (what the atomic write does): a UsageError if that
    fails (a read-only or pseudo file system such as /proc or /sys, a full disk, no permission)."""
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".qsid-probe-", suffix=".tmp")
    except OSError as exc:
        raise UsageError(f"argument {flag}: cannot create a file in {str(folder)!r} ({exc.strerror or exc})") from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)


def _checked_name(text: str, flag: str) -> Path:
    """``text`` as an output file name: not empty, not a folder (a trailing slash or an existing directory),
    not a link to nothing."""
    if not text.strip():
        raise UsageError(f"argument {flag}: give a file name; got {text!r}")
    example = "figure.png" if flag == "--figure" else "result.json" if flag == "--out" else "rows.csv"
    if text.endswith(("/", os.sep)):  # a folder, existing or not: never a file of that name
        raise UsageError(f"argument {flag}: {text!r} ends in '/': a folder; give a file name, e.g. {text + example!r}")
    out = Path(text)
    if out.is_dir():
        raise UsageError(f"argument {flag}: {text!r} is a directory; give a file name")
    if out.is_symlink():
        try:
            os.stat(out)  # (follows links: /dev/stdout into a pipe exists)
        except FileNotFoundError:
            raise UsageError(
                f"argument {flag}: {text!r} is a symbolic link to {os.readlink(out)!r}, which does not exist; "
                "give a file name, or remove the link"
            ) from None
        except OSError:  # a loop of links: said by output_target
            pass
    return out


def out_file(text: str | None, rep: Reporter, flag: str = "--out", inputs: Sequence[str | Path] = ()) -> Path | None:
    """Check an output file before any work: a file name (not a folder), not an input, a regular file or a new
    name, in a folder where a file can be created now (created if missing).

    An existing file is replaced, and that is said on stderr (before the run).
    """
    if text is None:
        return None
    out = _checked_name(text, flag)
    for inp in inputs:
        if _same_file(out, Path(inp)):
            raise UsageError(
                f"argument {flag}: {text!r} is the input file {str(inp)!r}; writing it would destroy "
                "the input, give another name"
            )
    parent = out.parent
    for up in (parent, *parent.parents):
        if up.exists():
            if not up.is_dir():
                raise UsageError(f"argument {flag}: {str(up)!r} is a file, not a directory")
            break
    try:
        parent.mkdir(parents=True, exist_ok=True)  # fail before the run, not after it
    except OSError as exc:
        raise UsageError(f"argument {flag}: cannot create {str(parent)!r}: {exc.strerror or exc}") from None
    check_writable(parent, flag)
    from qsid_core.errors import OutputPathError
    from qsid_core.studies import output_target

    try:
        target = output_target(out)  # the file a link points to, or the name itself
    except OutputPathError as exc:
        raise UsageError(f"argument {flag}: {exc}") from None
    _probe(target.parent, flag)  # where the atomic write puts its temporary file
    if out.exists():
        if not os.access(out, os.W_OK):
            raise UsageError(f"argument {flag}: {text!r} exists and is not writable")
        rep.line(f"note: {flag} {text} exists; it will be replaced")
    return out


def _fallback(path: Path, write: Callable[[Path], object]) -> Path | None:
    """Write the output meant for ``path`` to a new file in the temporary folder instead; None if that fails too."""
    fd, name = tempfile.mkstemp(prefix=f"qsid-{path.stem or 'output'}-", suffix=path.suffix)
    os.close(fd)
    try:
        write(Path(name))
    except (OSError, ValueError):
        with contextlib.suppress(OSError):
            os.unlink(name)
        return None
    return Path(name)


def save_output(path: Path, write: Callable[[Path], object], rep: Reporter | None = None, flag: str = "--out") -> Path:
    """``write(path)``; if writing fails this late (the disk filled, the folder went away), the same output goes to
    a file in the temporary folder and one line says where. Returns the file written.

    With ``rep`` the run goes on (its other outputs are written) and ends with exit status 2
    (:attr:`Reporter.lost`); without, a :class:`UsageError` carries that line.
    """
    check_stopped()  # a stop whose interrupt a library swallowed (e.g. in a finalizer) leaves the file as it was
    try:
        write(path)
        return path
    except (OSError, ValueError) as exc:  # qsid_core's OutputPathError is a ValueError
        why = getattr(exc, "strerror", None) or str(exc)
    try:
        safe = _fallback(path, write)
    except OSError:
        safe = None
    where = f"it was written to {str(safe)!r} instead" if safe else "nor could it be kept in the temporary folder"
    msg = f"cannot write {flag} {str(path)!r} ({why}); {where}"
    if rep is None:
        raise UsageError(msg)
    rep.line(f"error: {msg}")
    rep.lost.append(msg)
    return safe or path


def write_text(path: Path, text: str, rep: Reporter | None = None, flag: str = "--out") -> Path:
    """Write ``text`` to ``path`` atomically: a temporary file beside it, renamed over it when complete
    (an interrupted run never leaves a half-written file, and an existing one stays until then). A failure
    this late keeps the text in the temporary folder (:func:`save_output`)."""
    from qsid_core.studies import replace_atomically

    return save_output(Path(path), lambda p: replace_atomically(p, text), rep, flag)
