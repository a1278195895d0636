"""Reading a plant file (``.toml`` or ``.json``) however hostile it is: one :class:`SystemDefinitionError` line.

Every reader of a plant file (:func:`~qsid_core.plant.systems.load_system`,
:func:`~qsid_core.plant.nonlinear.is_nonlinear_file`, :func:`~qsid_core.plant.nonlinear.load_nonlinear`)
goes through :func:`read_plant_table`, so a missing file, a directory, a FIFO (never opened for a blocking
read: it would wait for a writer forever), a device, a loop of symbolic links, a huge file, bytes that are not
UTF-8, a parse error, lists nested a thousand deep (``RecursionError`` in the parsers) or a number of
thousands of digits is refused the same way wherever the file is read.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

from ..errors import SystemDefinitionError, short_repr
from ..validate import special_file_kind

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = ["MAX_FILE_BYTES", "read_plant_table"]

#: Largest plant file read (bytes).
MAX_FILE_BYTES = 10_000_000


def _reason(exc: BaseException) -> str:
    """An OS error in words, without repeating the (possibly very long) file name."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return short_repr(str(exc))


def _read_bytes(p: Path, shown: str) -> bytes:
    """The bytes of regular file ``p`` (at most MAX_FILE_BYTES), never blocking on a FIFO or a device."""
    try:
        st = os.stat(p)
    except (OSError, ValueError) as exc:  # missing, name too long, NUL byte, no permission, a loop of links
        why = "does not exist" if isinstance(exc, FileNotFoundError) else f"cannot be opened ({_reason(exc)})"
        raise SystemDefinitionError(f"system file {shown} {why}") from None
    kind = special_file_kind(st.st_mode) or (None if stat.S_ISREG(st.st_mode) else "not a file")
    if kind is not None:
        raise SystemDefinitionError(f"{shown} is {kind}, not a system file (.toml or .json)")
    if st.st_size > MAX_FILE_BYTES:
        raise SystemDefinitionError(f"system file {shown} is {st.st_size} bytes; at most {MAX_FILE_BYTES} allowed")
    try:  # non-blocking: a file swapped for a FIFO since the stat above cannot hang the read
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise SystemDefinitionError(f"system file {shown} cannot be opened ({_reason(exc)})") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise SystemDefinitionError(f"{shown} is not a regular file, not a system file (.toml or .json)")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise SystemDefinitionError(f"cannot read system file {p.name!r}: {_reason(exc)}") from None
    finally:
        os.close(fd)
    if len(data) > MAX_FILE_BYTES:
        raise SystemDefinitionError(f"system file {shown} is over {MAX_FILE_BYTES} bytes; at most that is allowed")
    return data


def read_plant_table(path: str | Path) -> dict[str, Any]:
    """The table of keys in plant file ``path`` (``.toml`` or ``.json``).

    Raises
    ------
    SystemDefinitionError
        One line naming the file and why it cannot be used: not a path, missing, not a regular file, too
        large, not UTF-8 text, not TOML/JSON, nested too deeply, a number too long, not one table of keys.
    """
    if not isinstance(path, (str, Path)):
        raise SystemDefinitionError(f"system file must be a path; got {short_repr(path)}")
    p = Path(path)
    shown = short_repr(str(p))
    suffix = p.suffix.lower()
    data = _read_bytes(p, shown)
    if suffix not in (".toml", ".json"):
        raise SystemDefinitionError(f"system file must end in .toml or .json; got {p.name!r}")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SystemDefinitionError(
            f"system file {p.name!r} is not UTF-8 text (byte {exc.start + 1} is {data[exc.start]:#04x}; binary?)"
        ) from None
    try:
        d = json.loads(text) if suffix == ".json" else tomllib.loads(text)
    except RecursionError:
        raise SystemDefinitionError(f"cannot parse {p.name}: lists or tables are nested too deeply") from None
    except ValueError as exc:  # parse errors of either format (tomllib's and json's are ValueErrors)
        msg = str(exc)
        if "integer string conversion" in msg:  # a number of thousands of digits
            msg = "a number has too many digits (more than 4300)"
        raise SystemDefinitionError(f"cannot parse {p.name}: {msg if len(msg) <= 200 else msg[:200] + ' …'}") from None
    if not isinstance(d, dict):
        raise SystemDefinitionError(
            f"system file {p.name!r} must hold a table/object with keys A and B (or vector_field, n and m)"
        )
    return d
