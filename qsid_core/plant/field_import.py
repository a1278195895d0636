"""The vector field a plant file names as ``"module:function"``, imported from where the file says.

A plant file's module may sit beside the file (``swing.toml`` and ``swing_field.py`` in one folder): then no
``PYTHONPATH`` is needed. The folder is searched only for the named module, and only after every other place
(it is put at the *end* of ``sys.path`` for the import and taken off again), so a file beside the plant never
hides an installed module or the standard library; a module of the same name found elsewhere first is an error
that says so. Such a field pickles as ``(reference, folder)`` (:class:`FileField`), so a worker process imports it
from the same folder. A module that is not beside the file is imported as any other (``PYTHONPATH``, installed).
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SystemDefinitionError, short_repr

__all__ = ["FileField", "resolve_field"]


def _beside(folder: Path, top: str) -> bool:
    """Whether module ``top`` is a file or package in ``folder``."""
    return (folder / f"{top}.py").is_file() or (folder / top / "__init__.py").is_file()


def _import_beside(mod: str, folder: Path) -> Any:
    """Import ``mod`` with ``folder`` searched last; the module must come from ``folder``."""
    where = str(folder)
    added = where not in sys.path
    if added:
        sys.path.append(where)
    try:
        module = importlib.import_module(mod)
    finally:
        if added and where in sys.path:
            sys.path.remove(where)
    found = Path(getattr(module, "__file__", None) or "").resolve()
    if folder not in found.parents:
        top = mod.partition(".")[0]
        raise SystemDefinitionError(
            f"module {top!r} beside the plant file is hidden by another module of that name ({found}): "
            "rename the file beside the plant (and its vector_field)"
        )
    return module


def resolve_field(ref: str, folder: str | Path | None = None) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """The callable named by ``"module:function"`` (a :class:`FileField` when the module sits in ``folder``).

    Raises
    ------
    SystemDefinitionError
        If ``ref`` is malformed, the module cannot be imported or the name is not callable (one line).
    """
    mod, sep, attr = ref.partition(":")
    if not sep or not mod or not attr:
        raise SystemDefinitionError(f"vector_field must be 'module:function'; got {short_repr(ref)}")
    here = Path(folder).resolve() if folder is not None else None
    beside = here is not None and _beside(here, mod.partition(".")[0])
    try:
        obj: Any = _import_beside(mod, here) if beside and here is not None else importlib.import_module(mod)
        for part in attr.split("."):
            obj = getattr(obj, part)
    except SystemDefinitionError:
        raise
    except Exception as exc:  # import errors of user code: one line
        raise SystemDefinitionError(f"vector_field {ref!r} cannot be loaded: {type(exc).__name__}: {exc}") from None
    if not callable(obj):
        raise SystemDefinitionError(f"vector_field {ref!r} is not callable")
    return FileField(ref, str(here), obj) if beside else obj


class FileField:
    """A vector field from a module beside its plant file: calls it, and pickles as ``(ref, folder)`` so that
    a worker process (which has not that folder on its path) imports it from the same folder."""

    __slots__ = ("ref", "folder", "fn")

    def __init__(self, ref: str, folder: str, fn: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> None:
        self.ref, self.folder, self.fn = ref, folder, fn

    def __call__(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return self.fn(x, u)

    def __reduce__(self) -> tuple[Any, tuple[str, str]]:
        return resolve_field, (self.ref, self.folder)

    def __repr__(self) -> str:
        return f"FileField({self.ref!r} from {self.folder!r})"
