"""What leaves a front end besides its settings file: the ``qsid sweep`` / ``qsid bits`` lines that reproduce its
numbers, and exports of the current curves (CSV, JSON) and figures (one standalone offline HTML page), for a
linear and a nonlinear plant alike (the columns and captions chosen by what the frame's result holds). Pure
functions of a frame or of the panel's values; the dashboard puts them on the panel's buttons
(:mod:`app.dashboard.share`).
"""

from __future__ import annotations

import csv
import dataclasses
import enum
import html
import io
import json
import math
from functools import lru_cache
from typing import Any

from app.figures.raw import PLOT_CONFIG
from app.settings.command import bits_command, budget_command, sweep_argv, sweep_command
from app.settings.config import study_config
from app.settings.values import Values, is_nonlinear
from qsid_core.studies import KoopmanConfig, json_clean

from .frame import lifted

__all__ = ["command_lines", "curves_rows", "curves_csv", "curves_json", "figures_html", "frame_html"]


def command_lines(v: Values) -> list:
    """``qsid sweep`` lines reproducing the panel's numbers (one per estimator when both are shown), then with a bit
    budget its ``qsid budget`` line (judged on the last estimator, as the bandwidth view) and, with bits per sample,
    the allocation's, and for a linear plant the ``qsid bits`` line."""
    return list(_lines(v) if not is_nonlinear(v.system) else _command_lines(v))


@lru_cache(maxsize=64)
def _lines(v: Values) -> tuple[str, ...]:
    """A linear plant's :func:`command_lines`, made once per values (a tab shows them after every draw)."""
    return tuple(_command_lines(v))


def _command_lines(v: Values) -> list:
    sc = study_config(v)
    cfg = sc.config
    lines = [sweep_command(dataclasses.replace(cfg, estimator=e)) for e in sc.estimators]  # either kind of plant
    if float(v.total_bits):
        last = sweep_argv(dataclasses.replace(cfg, estimator=sc.estimators[-1]))
        lines.append(budget_command(last, float(v.total_bits)))
        if int(v.bits_per_sample):
            lines.append(budget_command(last, float(v.total_bits), int(v.bits_per_sample)))
    if isinstance(cfg, KoopmanConfig):
        return lines
    return lines + [bits_command(cfg, float(v.target), float(v.cost_gap))]


_COLUMNS = (
    "estimator",
    "bits",
    "err_A_mean",
    "err_A_std",
    "err_B_mean",
    "err_B_std",
    "err_A_theory",
    "err_B_theory",
    "overload_fraction",
    "mpc_cost_mean",
    "mpc_cost_std",
    "mpc_failed",
    "ultimate_bound",
    "ultimate_bound_realized_median",
    "ultimate_bound_realized_max",
    "final_state_norm_mean",
    "theorem1_holds",
    "bcls_holds",
    "stabilized_fraction",
    "converged",
    "bounded",
    "diverged",
    "failed",
    "steady_state_error_mean",
    "tracking_error_mean",
)


#: The CSV columns of a nonlinear plant's curves (the rows of ``qsid sweep --json``'s ``results``).
_LIFTED_COLUMNS = (
    "estimator",
    "bits",
    "err_G_mean",
    "err_G_std",
    "err_A_mean",
    "err_A_std",
    "err_B_mean",
    "err_B_std",
    "large_data_err_G",
    "prediction_error_mean",
    "prediction_error_std",
    "overload_fraction",
    "bcls_fallbacks",
    "ident_failures",
    "stabilized_fraction",
    "converged",
    "bounded",
    "diverged",
    "failed",
    "within_radius",
    "settled_offset_median",
    "settled_offset_max",
)


def curves_rows(frame) -> list:
    """One flat row per (estimator, b) of the curves computed so far."""
    if lifted(frame):
        return _lifted_rows(frame)
    out = []
    for lab in frame.labels:
        for b, r in sorted(frame.rows[lab].items()):
            cost, fsn = r.get("mpc_cost") or {}, r.get("final_state_norm") or {}
            real, a = r.get("ultimate_bound_realized") or {}, r.get("assumptions") or {}
            out.append(
                {
                    "estimator": lab,
                    "bits": b,
                    "err_A_mean": r["err_A"]["mean"],
                    "err_A_std": r["err_A"]["std"],
                    "err_B_mean": r["err_B"]["mean"],
                    "err_B_std": r["err_B"]["std"],
                    "err_A_theory": r.get("err_A_theory"),
                    "err_B_theory": r.get("err_B_theory"),
                    "overload_fraction": r.get("overload_fraction"),
                    "mpc_cost_mean": cost.get("mean"),
                    "mpc_cost_std": cost.get("std"),
                    "mpc_failed": cost.get("failed"),
                    "ultimate_bound": r.get("ultimate_bound"),
                    "ultimate_bound_realized_median": real.get("median"),
                    "ultimate_bound_realized_max": real.get("max"),
                    "final_state_norm_mean": fsn.get("mean"),
                    "theorem1_holds": a.get("theorem1_holds"),
                    "bcls_holds": a.get("bcls_holds"),
                    "stabilized_fraction": r.get("stabilized_fraction"),
                    **{
                        k: (r.get("closed_loop_outcomes") or {}).get(k)
                        for k in ("converged", "bounded", "diverged", "failed")
                    },
                    "steady_state_error_mean": (r.get("steady_state_error") or {}).get("mean"),
                    "tracking_error_mean": (r.get("tracking_error") or {}).get("mean"),
                }
            )
    return out


def curves_csv(frame) -> str:
    """The current curves as CSV (header + one row per estimator and b; empty cells for missing values)."""
    if lifted(frame):
        return _lifted_csv(frame)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in curves_rows(frame):
        w.writerow(
            {k: ("" if v is None or (isinstance(v, float) and not math.isfinite(v)) else v) for k, v in r.items()}
        )
    return buf.getvalue()


def _plain(obj: object) -> object:
    """What :func:`json.dumps` cannot write itself: an enum as its value."""
    if isinstance(obj, enum.Enum):
        return obj.value
    raise TypeError(f"{type(obj).__name__} is not JSON data")


def _dumps(obj: object) -> str:
    """Strict JSON (non-finite numbers as null, numpy values plain), as the CLI writes it."""
    return json.dumps(json_clean(obj), indent=2, allow_nan=False, default=_plain)


def curves_json(frame) -> str:
    """The current curves, settings and command as strict JSON (rows as the CLI's ``results``)."""
    if lifted(frame):
        return _dumps(_lifted_json(frame))
    return _dumps(
        {
            "system": frame.system.name,
            "settings": dataclasses.asdict(frame.values),
            "command": command_lines(frame.values),
            "bits_drawn": frame.bits,
            "complete": frame.done >= frame.total,
            "mpc_cost_true_model": frame.true_cost,
            "curves": {lab: [frame.rows[lab][b] for b in sorted(frame.rows[lab])] for lab in frame.labels},
        }
    )


def figures_html(figures: dict, title: str, caption: str) -> str:
    """Plotly figures on one standalone page (plotly.js inlined once: works offline, one file)."""
    import plotly.io as pio
    from plotly.offline import get_plotlyjs

    divs = [
        f'<div class="panel"><h2>{html.escape(fig.layout.title.text or name)}</h2>\n'
        + pio.to_html(
            fig,
            include_plotlyjs=False,
            full_html=False,
            div_id=f"fig-{name}",
            config={"responsive": True, **PLOT_CONFIG},
        )
        + "\n</div>"
        for name, fig in figures.items()
    ]
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<script>{get_plotlyjs()}</script>\n"
        "<style>body{font-family:system-ui,sans-serif;margin:1em 2em;color:#222}"
        ".panel{border:1px solid #ddd;border-radius:4px;padding:.3em;margin-bottom:1em}"
        ".panel h2{font-size:1em;margin:.2em .4em}code{white-space:pre-wrap}</style></head>\n<body>\n"
        f"<h1>{html.escape(title)}</h1>\n<p>{caption}</p>\n" + "\n".join(divs) + "\n</body></html>\n"
    )


def frame_html(frame) -> str:
    """The current figures of ``frame`` (every registered view) as one offline page, with the command."""
    from .render import build_figures

    if lifted(frame):
        name = frame.system.name
        return figures_html(build_figures(frame), f"qsid dashboard: {name}", _lifted_caption(frame))
    cmds = "<br>".join(f"<code>{html.escape(c)}</code>" for c in command_lines(frame.values))
    caption = (
        f"System {html.escape(frame.system.name)}, b = {frame.bits} drawn, {frame.done}/{frame.total} word "
        f"lengths computed. Reproduce the numbers: {cmds}"
    )
    figs = build_figures(frame)
    if getattr(frame, "datalength", None) is None:  # not computed: no empty "press Compute" plot in the page
        figs.pop("datalength", None)
    return figures_html(figs, f"qsid dashboard: {frame.system.name}", caption)


# ----- a nonlinear plant's curves (its rows are the nonlinear sweep's) -------------------------------------------
def _lifted_rows(frame: Any) -> list[dict[str, Any]]:
    """One flat row per (estimator, b) computed so far."""
    out = []
    for lab in frame.labels:
        for b, r in sorted(frame.rows[lab].items()):
            oc = r.get("closed_loop_outcomes") or {}
            row: dict[str, Any] = {"estimator": lab, "bits": b}
            for k in ("err_G", "err_A", "err_B", "prediction_error"):
                row[f"{k}_mean"], row[f"{k}_std"] = r[k]["mean"], r[k]["std"]
            row["large_data_err_G"] = (r.get("large_data") or {}).get("err_G")
            for k in ("overload_fraction", "bcls_fallbacks", "ident_failures", "stabilized_fraction"):
                row[k] = r.get(k)
            row.update({k: oc.get(k) for k in ("converged", "bounded", "diverged", "failed")})
            off = r.get("settled_offset") or {}
            row.update(
                within_radius=r.get("within_radius"),
                settled_offset_median=off.get("median"),
                settled_offset_max=off.get("max"),
            )
            out.append(row)
    return out


def _lifted_csv(frame: Any) -> str:
    """The curves as CSV (empty cells for missing values)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_LIFTED_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in _lifted_rows(frame):
        w.writerow({k: "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else x for k, x in r.items()})
    return buf.getvalue()


def _lifted_json(frame: Any) -> dict[str, Any]:
    """The curves, settings and command lines (rows as ``qsid sweep --json``'s ``results``)."""
    return {
        "kind": "koopman",
        "system": frame.system.name,
        "settings": dataclasses.asdict(frame.values),
        "command": command_lines(frame.values),
        "bits_drawn": frame.bits,
        "complete": frame.complete,
        "reference": {
            "prediction_error": frame.reference_error,
            "closed_loop_outcome": frame.reference_loop.outcome[0] if frame.reference_loop is not None else None,
            "settled_offset": _offset(frame.reference_loop),
        },
        "curves": {lab: [frame.rows[lab][b] for b in sorted(frame.rows[lab])] for lab in frame.labels},
    }


def _offset(loop: Any) -> float | None:
    """The settled offset of the unquantized EDMD's loop (None: no loop, or it diverged or failed)."""
    if loop is None or not len(loop.settled_offset) or not math.isfinite(float(loop.settled_offset[0])):
        return None
    return float(loop.settled_offset[0])


def _lifted_caption(frame: Any) -> str:
    """The offline page's caption of a nonlinear frame, with the command lines (HTML)."""
    cmds = "<br>".join(f"<code>{html.escape(c)}</code>" for c in command_lines(frame.values))
    return (
        f"Nonlinear plant {html.escape(frame.system.name)}, b = {frame.bits} drawn, {frame.done}/{frame.total} word "
        f"lengths with loops. Reproduce the numbers: {cmds}"
    )
