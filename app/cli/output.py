"""Output formats of ``qsid``: strict JSON, and the readable sweep table."""

from __future__ import annotations

import enum
import json
import math
from typing import Any

__all__ = ["clean", "dumps", "g", "format_table"]


def clean(obj: Any) -> Any:
    """JSON-ready copy: non-finite floats become None, numpy scalars/arrays plain Python, enums their value."""
    if isinstance(obj, enum.Enum):
        return clean(obj.value)
    if isinstance(obj, dict):
        return {str(k.value if isinstance(k, enum.Enum) else k): clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [clean(v) for v in obj]
    if hasattr(obj, "tolist") and not isinstance(obj, (str, bytes)):
        return clean(obj.tolist())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    return obj


def dumps(obj: Any, indent: int | None = 2) -> str:
    return json.dumps(clean(obj), indent=indent, allow_nan=False)


def g(v, fmt: str = ".3g", none: str = "-") -> str:
    return none if v is None else format(v, fmt)


def _pm(stats: dict | None) -> str:
    if not stats or stats.get("mean") is None:
        return "-"
    return f"{stats['mean']:.3e} +/- {stats['std']:.1e}"


def format_table(d: dict) -> str:
    """The readable table of a sweep dict (``SweepResult.to_dict()``)."""
    head = ["b", "eps min..max", "err_A mean +/- std", "Thm1 A", "err_B mean +/- std", "Thm1 B", "overload",
            "MPC cost (failed)", "delta bound", "|x_T| mean"]
    rows = []
    for r in d["results"]:
        eps = list(r["eps_x"]) + list(r["eps_u"])
        cost = r.get("mpc_cost")
        cost_s = "-" if cost is None else f"{g(cost.get('mean'), '.4g')} ({cost.get('failed', 0)})"
        fsn = r.get("final_state_norm")
        rows.append([
            str(r["bits"]),
            f"{min(eps):.2e}..{max(eps):.2e}",
            _pm(r["err_A"]),
            g(r["err_A_theory"], ".3e"),
            _pm(r["err_B"]),
            g(r["err_B_theory"], ".3e"),
            f"{100 * r['overload_fraction']:.2f}%",
            cost_s,
            g(r["ultimate_bound"], ".3e"),
            "-" if fsn is None else g(fsn.get("mean"), ".2e"),
        ])
    # hand-written rather than rich.Table: this exact plain-text layout is the documented, diff-able stdout
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(head)]
    left = {1}

    def fmt(cells):
        return "  ".join(c.ljust(w) if i in left else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))

    c = d["config"]
    lines = [
        f"system {d['system']}: {c['trajectories']} x {c['steps']} samples, {c['realizations']} realizations, "
        f"range {c['range']}{' + guard' if c['guard'] else ''}, dither {c['dither']}, estimator {c['estimator']}"
        + ("" if c["mpc"] is None else
           f", MPC horizon {c['mpc']['horizon']}, {c['mpc']['steps']} steps, u_max "
           f"{','.join(format(u, 'g') for u in c['mpc']['u_max'])}"),
        fmt(head),
        fmt(["-" * w for w in widths]),
        *(fmt(row) for row in rows),
    ]
    t = d.get("timing_s", {})
    slope = (f"slope of log10 mean error per bit: A {g(d.get('slope_A'), '+.3f')}, "
             f"B {g(d.get('slope_B'), '+.3f')} (letter: -0.301 = -log10 2)")
    true_cost = ("MPC off" if c["mpc"] is None else
                 f"true-model MPC cost {g(d.get('mpc_cost_true_model'), '.4g')}")
    timing = "time " + ", ".join(f"{k} {v:.2f} s" for k, v in t.items())
    lines.append(f"{slope}; {true_cost}; {timing}")
    fails: dict = {}
    for r in d["results"]:
        for kind, k in ((r.get("mpc_cost") or {}).get("failures") or {}).items():
            fails[kind] = fails.get(kind, 0) + k
    if fails:
        lines.append("MPC failures by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(fails.items())))
    fb = sum(r.get("bcls_fallbacks", 0) for r in d["results"])
    if fb:
        lines.append(f"BCLS fell back to LS in {fb} realization(s) (corrected Gram matrix not positive definite)")
    return "\n".join(lines)
