"""The engine's layout: subpackages by concept in one order, one public API each, and front ends that use
only public names."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CORE = ROOT / "qsid_core"

#: The subpackages, each building only on those before it.
ORDER = ("plant", "quantization", "identification", "control", "studies")
#: Modules beside the subpackages, which every subpackage may use.
BASE = ("errors", "validate", "version")


def _engine_imports(path: Path) -> set[str]:
    """The ``qsid_core`` modules or packages a module of the engine imports (relative imports resolved)."""
    rel = path.relative_to(ROOT).with_suffix("")
    pkg = list(rel.parts[:-1])
    out = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - node.level + 1] + ([node.module] if node.module else [])
                mod = ".".join(base)
            else:
                mod = node.module or ""
            if mod.startswith("qsid_core"):
                out.add(mod)
                out.update(f"{mod}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("qsid_core"))
    return out


def _subpackage(dotted: str) -> str | None:
    parts = dotted.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in ORDER else None


def test_the_engine_is_the_subpackages_and_the_base_modules():
    top = {p.stem for p in CORE.glob("*.py")} - {"__init__"}
    dirs = {p.name for p in CORE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert top == set(BASE)
    assert dirs == set(ORDER)


@pytest.mark.parametrize("sub", ORDER)
def test_a_subpackage_imports_only_earlier_ones(sub):
    allowed = set(ORDER[: ORDER.index(sub) + 1])
    wrong = []
    for path in sorted((CORE / sub).glob("*.py")):
        for dotted in _engine_imports(path):
            other = _subpackage(dotted)
            if other is not None and other not in allowed:
                wrong.append(f"{path.relative_to(ROOT)} imports {dotted}")
    assert wrong == []


def test_the_base_modules_import_no_subpackage():
    for name in BASE:
        assert not [d for d in _engine_imports(CORE / f"{name}.py") if _subpackage(d)], name


def test_the_order_check_sees_a_wrong_import(tmp_path):
    bad = tmp_path / "qsid_core" / "plant" / "x.py"
    bad.parent.mkdir(parents=True)
    bad.write_text("from ..studies.sweep import run_sweep\n")
    rel_root = tmp_path
    imports = set()
    for node in ast.walk(ast.parse(bad.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level:
            pkg = list(bad.relative_to(rel_root).with_suffix("").parts[:-1])
            imports.add(".".join(pkg[: len(pkg) - node.level + 1] + [node.module]))
    assert {_subpackage(d) for d in imports} == {"studies"}


@pytest.mark.parametrize("sub", ORDER)
def test_every_subpackage_has_one_sorted_public_api_that_resolves(sub):
    mod = importlib.import_module(f"qsid_core.{sub}")
    names = list(mod.__all__)
    assert names == sorted(names) and len(set(names)) == len(names)
    for n in names:
        assert hasattr(mod, n), f"qsid_core.{sub}.{n}"


def test_the_top_level_api_is_one_sorted_list_of_subpackage_names():
    import qsid_core

    src = (CORE / "__init__.py").read_text(encoding="utf-8")
    assert "__all__ +=" not in src
    names = list(qsid_core.__all__)
    key = [n.lower().lstrip("_") for n in names]
    assert key == sorted(key) and len(set(names)) == len(names)
    subs = [importlib.import_module(f"qsid_core.{s}") for s in ORDER]
    for n in names:
        obj = getattr(qsid_core, n)
        assert (
            n in ("__version__", "RECORD_COLUMNS")
            or any(getattr(s, n, None) is obj for s in subs)
            or n in (importlib.import_module("qsid_core.errors").__all__)
        ), n


def _front_end_imports():
    for folder in ("app", "examples"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if isinstance(node, ast.ImportFrom) and not node.level and (node.module or "").startswith("qsid_core"):
                    yield path, node.module, [a.name for a in node.names]
                elif isinstance(node, ast.Import):
                    for a in node.names:
                        if a.name.startswith("qsid_core."):
                            yield path, a.name, []


def test_front_ends_import_public_names_only():
    """``app/`` and ``examples/`` import from ``qsid_core`` or a subpackage, and only names in its ``__all__``."""
    wrong = []
    for path, module, names in _front_end_imports():
        where = f"{path.relative_to(ROOT)}: {module}"
        if module.count(".") > 1 or (module.count(".") == 1 and _subpackage(module) is None):
            if module not in {f"qsid_core.{b}" for b in BASE}:
                wrong.append(f"{where} (a module inside a subpackage)")
                continue
        public = importlib.import_module(module).__all__
        wrong += [f"{where}.{n} (not public)" for n in names if n not in public]
    assert wrong == []
