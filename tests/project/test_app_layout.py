"""The layout rules of app/ and qsid_core/: small modules and functions, no import cycles; commands and views
stay independent of each other.

Size is counted twice. In *logical* lines (statements, as the tokenizer ends them): no module over 300, no
function over 60, so the formatter spreading one call over several lines does not change it. And in
*physical* lines as formatted (what a reader scrolls through, tables and docstrings included): no module over
400, no function over 80.
"""

from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
APP = ROOT / "app"
PACKAGES = ("app", "qsid_core")


def _modules(package: str = "app") -> dict:
    """module name -> (path, parsed tree) of every module of ``package``."""
    out = {}
    for p in sorted((ROOT / package).rglob("*.py")):
        if "__pycache__" in p.parts:  # generated at run time (qsid_core.quantization.unrolled), not the project's code
            continue
        rel = p.relative_to(ROOT).with_suffix("")
        name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        out[name] = (p, ast.parse(p.read_text(encoding="utf-8")))
    return out


def _imports(name: str, path: Path, tree: ast.AST, known: set) -> set:
    """app modules ``name`` imports (a package import also runs the package's __init__)."""
    deps = set()
    pkg = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = (
                ".".join(pkg[: len(pkg) - node.level + 1] + [node.module or ""]).strip(".")
                if node.level
                else node.module
            )
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        elif isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            continue
        for t in targets:
            parts = t.split(".")
            for i in range(1, len(parts) + 1):  # the target and every parent package
                m = ".".join(parts[:i])
                if m in known and m != name and not name.startswith(m + "."):
                    deps.add(m)
    return deps


def _cycles(graph: dict) -> list:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def _logical_line_ends(source: str) -> list[int]:
    """The physical line on which each logical line (statement) of ``source`` ends."""
    tokens = tokenize.generate_tokens(io.StringIO(source).readline)
    return [t.start[0] for t in tokens if t.type == tokenize.NEWLINE]


@pytest.mark.parametrize("package", PACKAGES)
def test_no_module_over_300_statements_no_function_over_60(package):
    too_long = []
    for name, (path, tree) in _modules(package).items():
        ends = _logical_line_ends(path.read_text(encoding="utf-8"))
        if len(ends) > 300:
            too_long.append(f"{name}: {len(ends)} logical lines")
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                k = sum(1 for e in ends if node.lineno <= e <= node.end_lineno)
                if k > 60:
                    too_long.append(f"{name}.{node.name}: {k} logical lines")
    assert too_long == []


#: Physical-line limits, as formatted (``ruff format``): a module, a function (its decorators excluded).
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80

#: Modules exempt from the physical-line limits, each with a comment saying why; none is now.
PHYSICAL_LIMITS_WAIVED: set[str] = set()


def _physical_too_long(name: str, source: str, tree: ast.AST) -> list[str]:
    """What in module ``name`` is over the physical-line limits."""
    out = []
    lines = source.count("\n") + (not source.endswith("\n") and bool(source))
    if lines > MAX_MODULE_LINES:
        out.append(f"{name}: {lines} lines")
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            k = node.end_lineno - node.lineno + 1
            if k > MAX_FUNCTION_LINES:
                out.append(f"{name}.{node.name}: {k} lines")
    return out


@pytest.mark.parametrize("package", PACKAGES)
def test_no_module_over_400_lines_no_function_over_80_as_formatted(package):
    too_long = []
    for name, (path, tree) in _modules(package).items():
        if name not in PHYSICAL_LIMITS_WAIVED:
            too_long += _physical_too_long(name, path.read_text(encoding="utf-8"), tree)
    assert too_long == []


def test_the_waived_modules_exist():
    known = set(_modules("app")) | set(_modules("qsid_core"))
    assert PHYSICAL_LIMITS_WAIVED <= known, PHYSICAL_LIMITS_WAIVED - known


def test_the_physical_rule_counts_every_line():
    fits = "def f():\n" + "".join(f"    x{i} = {i}\n" for i in range(79))  # 80 lines with the def
    over = fits + "    x79 = 79\n"
    assert _physical_too_long("m", fits, ast.parse(fits)) == []
    assert _physical_too_long("m", over, ast.parse(over)) == ["m.f: 81 lines"]
    module = "x = 1\n" * 401
    assert _physical_too_long("m", module, ast.parse(module)) == ["m: 401 lines"]


def test_the_size_rule_counts_statements_not_physical_lines():
    one_call_spread = "f(\n    1,\n    2,\n)\nx = 1\n"
    assert len(_logical_line_ends(one_call_spread)) == 2


@pytest.mark.parametrize("package", PACKAGES)
def test_no_import_cycles(package):
    mods = _modules(package)
    graph = {name: _imports(name, p, t, set(mods)) for name, (p, t) in mods.items()}
    if package == "app":
        assert graph["app.cli.reproduce"] >= {"app.cli.runner"}  # the check sees relative imports
    else:
        assert graph["qsid_core.studies.sweep"] >= {"qsid_core.studies.experiment"}
    assert _cycles(graph) == []


def test_the_cycle_check_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_commands_import_the_runner_never_each_other():
    mods = _modules()
    commands = {"app.cli.systems", "app.cli.sweep", "app.cli.reproduce"}
    for name in commands:
        deps = _imports(name, *mods[name], set(mods))
        assert not deps & commands, name


def test_every_view_module_is_registered_and_imports_no_other_view():
    from app.figures import registry

    mods = _modules()
    view_modules = {f"app.figures.{v.build.__module__.rsplit('.', 1)[-1]}" for v in registry.VIEWS}
    assert view_modules == {
        "app.figures.error_vs_bits",
        "app.figures.cost",
        "app.figures.bound",
        "app.figures.eigenvalues",
        "app.figures.time_series",
        "app.figures.quantizer",
        "app.figures.datalength",
        "app.figures.bandwidth",
        "app.figures.compare",
        "app.figures.norm_time",
        "app.figures.bits_needed",
        "app.figures.residual",
    }
    for name in view_modules:
        assert not _imports(name, *mods[name], set(mods)) & view_modules, name
    # a nonlinear plant's views: the same modules where the quantity is the same, else a view named for what it shows
    lifted = {f"app.figures.{v.build.__module__.rsplit('.', 1)[-1]}" for v in registry.KOOPMAN_VIEWS}
    assert lifted == {
        "app.figures.error_vs_bits",
        "app.figures.eigenvalues",
        "app.figures.prediction_error",
        "app.figures.loop_outcomes",
        "app.figures.bandwidth",
    }
    every = view_modules | lifted
    for name in lifted:
        assert not _imports(name, *mods[name], set(mods)) & every, name


def test_no_twin_module_per_plant_kind():
    """One path for both plant kinds: no ``koopman_*`` module in ``app/`` or the engine's studies: one module serves either kind."""
    twins = [*(ROOT / "app").rglob("koopman_*.py"), *(ROOT / "qsid_core/studies").glob("koopman_*.py")]
    assert twins == []


@pytest.mark.parametrize("package", PACKAGES)
def test_no_module_imports_another_modules_private_names(package):
    """A name another module needs is public (in its ``__all__``); viser's internals stay in app.dashboard.viserfix."""
    found = []
    for name, (_, tree) in _modules(package).items():
        for node in ast.walk(tree):
            if not isinstance(node, ast.ImportFrom) or node.module == "__future__":
                continue
            if name == "app.dashboard.viserfix" and (node.module or "").startswith("viser"):
                continue
            found += [
                f"{name}: {node.module}.{a.name}"
                for a in node.names
                if a.name.startswith("_") and not a.name.endswith("__")
            ]
    assert found == []


#: The dashboard is viser wiring: at most this many modules (every .py file, ``__init__`` and
#: ``__main__`` included) on at most this many import levels; what needs no GUI lives in ``app/settings``,
#: ``app/frames`` and ``app/lessons``.
DASHBOARD_MAX_MODULES = 20
DASHBOARD_MAX_LEVELS = 8


def _levels(graph: dict) -> dict:
    """Each module's import level in ``graph`` (module -> the modules it imports, within the graph): 1 for a module
    importing none of them, else 1 + the highest level of those it imports (an import cycle raises)."""
    out: dict = {}

    def level(m: str, path: tuple) -> int:
        if m in path:
            raise ValueError(f"import cycle: {' -> '.join(path + (m,))}")
        if m not in out:
            out[m] = 1 + max((level(d, path + (m,)) for d in graph[m]), default=0)
        return out[m]

    for m in graph:
        level(m, ())
    return out


def _chain(graph: dict, levels: dict, top: str) -> list:
    """The longest import chain down from ``top`` (for the failure message)."""
    chain = [top]
    while graph[chain[-1]]:
        chain.append(max(graph[chain[-1]], key=levels.get))
    return chain


def _package_imports(name: str, tree: ast.AST, package: str) -> set:
    """``{package}`` if module ``name`` imports the package itself (``from app.dashboard import main``: its
    ``__init__`` runs), which :func:`_imports` leaves out for a package's own modules."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and not node.level and node.module == package:
            if any(f"{package}.{a.name}" not in _modules() for a in node.names):
                return {package} if name != package else set()
        if isinstance(node, ast.Import) and any(a.name == package for a in node.names) and name != package:
            return {package}
    return set()


def test_the_dashboard_is_at_most_20_modules_on_at_most_8_import_levels_without_cycles():
    mods = {name: v for name, v in _modules().items() if name == "app.dashboard" or name.startswith("app.dashboard.")}
    files = sorted((APP / "dashboard").glob("*.py"))
    assert len(mods) == len(files)  # every .py file, __init__ and __main__ included
    graph = {
        name: _imports(name, p, t, set(mods)) | _package_imports(name, t, "app.dashboard")
        for name, (p, t) in mods.items()
    }
    assert graph["app.dashboard.__main__"] == {"app.dashboard"}  # a package import counts (its __init__ runs)
    assert _cycles(graph) == []
    levels = _levels(graph)
    top = max(levels, key=levels.get)
    assert len(files) <= DASHBOARD_MAX_MODULES, [p.name for p in files]
    assert levels[top] <= DASHBOARD_MAX_LEVELS, " -> ".join(_chain(graph, levels, top))
    assert not [p.name for p in files if p.name.startswith("koopman_")]  # one path for both kinds of plant


def test_the_level_count_catches_a_chain_too_deep_and_a_cycle():
    chain = {f"m{i}": ({f"m{i + 1}"} if i < 8 else set()) for i in range(9)}  # m0 -> m1 -> ... -> m8
    levels = _levels(chain)
    assert levels["m8"] == 1 and levels["m0"] == 9 > DASHBOARD_MAX_LEVELS
    assert _chain(chain, levels, "m0") == [f"m{i}" for i in range(9)]
    assert _levels({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == {"a": 3, "b": 2, "c": 1}
    with pytest.raises(ValueError, match="import cycle"):
        _levels({"a": {"b"}, "b": {"a"}})
