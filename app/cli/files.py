"""The files a ``qsid`` command reads and writes: an output file checked before any work (a name, not a
directory, not an input, writable), the inputs it must never overwrite, and an atomic write."""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from app.stop import check_stopped

from .parser import UsageError

if TYPE_CHECKING:
    from .runner import Reporter

__all__ = ["check_writable", "input_files", "out_file", "write_text"]


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


def out_file(text: str | None, rep: Reporter, flag: str = "--out", inputs: Sequence[str | Path] = ()) -> Path | None:
    """Check an output file before any work: a name, not a directory, not an input, writable.

    An existing file is replaced, and that is said on stderr (before the run).
    """
    if text is None:
        return None
    if not text.strip():
        raise UsageError(f"argument {flag}: give a file name; got {text!r}")
    out = Path(text)
    if out.is_dir():
        raise UsageError(f"argument {flag}: {text!r} is a directory; give a file name")
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
        output_target(out)
    except OutputPathError as exc:
        raise UsageError(f"argument {flag}: {exc}") from None
    if out.exists():
        if not os.access(out, os.W_OK):
            raise UsageError(f"argument {flag}: {text!r} exists and is not writable")
        rep.line(f"note: {flag} {text} exists; it will be replaced")
    return out


def write_text(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically: a temporary file beside it, renamed over it when complete
    (an interrupted run never leaves a half-written file, and an existing one stays until then)."""
    from qsid_core.studies import replace_atomically

    check_stopped()  # a stop whose interrupt a library swallowed (e.g. in a finalizer) leaves the file as it was
    replace_atomically(Path(path), text)
