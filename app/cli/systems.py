"""``qsid systems``: list the preset systems (name, states n, inputs m, description)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from .output import dumps

if TYPE_CHECKING:
    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run"]

HELP = "list the preset systems"
DESCRIPTION = "List the preset systems (name, states n, inputs m, description)."


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")


def _item(name: str, s: Any) -> dict[str, Any]:
    """One preset's row (a linear or a nonlinear plant: both have n, m, dt, description and names)."""
    return {
        "name": name,
        "n": s.n,
        "m": s.m,
        "dt": s.dt,
        "description": s.description,
        "states": list(s.state_names),
        "inputs": list(s.input_names),
    }


def run(args: argparse.Namespace, rep: Reporter) -> int:
    from qsid_core import PRESETS
    from qsid_core.plant import NONLINEAR_PRESETS

    items = [_item(name, make()) for name, make in PRESETS.items()]
    items += [{**_item(name, make()), "nonlinear": True} for name, make in NONLINEAR_PRESETS.items()]
    if args.json:
        print(dumps(items))
        return 0
    w = max(len("name"), *(len(i["name"]) for i in items))
    print(f"{'name'.ljust(w)}  n  m  description")
    for i in items:
        print(f"{i['name'].ljust(w)}  {i['n']}  {i['m']}  {i['description']}")
    print("custom systems: --system FILE.toml|FILE.json with A, B and optional x0, Q, R, dt")
    print(
        f"nonlinear plants (Koopman/EDMD, --lifting poly:D|rbf:K|identity): {', '.join(NONLINEAR_PRESETS)}, "
        "or FILE.toml|FILE.json with vector_field = 'module:function', n, m and optional dt, x0, Q, R"
    )
    return 0
