"""What leaves the dashboard besides its settings file: the ``qsid sweep`` / ``qsid bits`` lines that
reproduce a tab's numbers, and exports of the current curves (CSV, JSON) and figures (one standalone offline
HTML page). Pure functions of a frame or of the panel's values; :mod:`app.dashboard.share` puts them on the
panel's buttons.
"""

from __future__ import annotations

import csv
import dataclasses
import enum
import html
import io
import json
import math

from app.figures.raw import PLOT_CONFIG
from app.settings.command import bits_command, budget_command, sweep_argv, sweep_command
from app.settings.koopman_command import koopman_argv
from qsid_core.studies import json_clean

from .koopman_exports import koopman_caption, koopman_csv, koopman_json_data, koopman_lines, koopman_rows
from .koopman_settings import is_nonlinear, koopman_config
from .settings import Values, estimators, resolve_system, sweep_config

__all__ = ["command_lines", "curves_rows", "curves_csv", "curves_json", "figures_html", "frame_html"]


def command_lines(v: Values) -> list:
    """``qsid sweep`` lines reproducing the panel's numbers (one per estimator when both are shown), then with a bit
    budget its ``qsid budget`` line (judged on the last estimator, as the bandwidth view)."""
    if is_nonlinear(v.system):
        kcfg, kests = koopman_config(v)
        budget = [budget_command(koopman_argv(dataclasses.replace(kcfg, estimator=kests[-1])), float(v.total_bits))]
        return koopman_lines(v) + (budget if float(v.total_bits) else [])
    system = resolve_system(v).system
    cfg = sweep_config(v, system)
    ests = estimators(v.identification)
    lines = [sweep_command(dataclasses.replace(cfg, estimator=e)) for e in ests]
    if float(v.total_bits):
        lines.append(budget_command(sweep_argv(dataclasses.replace(cfg, estimator=ests[-1])), float(v.total_bits)))
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


def curves_rows(frame) -> list:
    """One flat row per (estimator, b) of the curves computed so far."""
    if getattr(frame, "kind", "") == "koopman":
        return koopman_rows(frame)
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
    if getattr(frame, "kind", "") == "koopman":
        return koopman_csv(frame)
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
    if getattr(frame, "kind", "") == "koopman":
        return _dumps(koopman_json_data(frame))
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

    if getattr(frame, "kind", "") == "koopman":
        name = frame.system.name
        return figures_html(build_figures(frame), f"qsid dashboard: {name}", koopman_caption(frame))
    cmds = "<br>".join(f"<code>{html.escape(c)}</code>" for c in command_lines(frame.values))
    caption = (
        f"System {html.escape(frame.system.name)}, b = {frame.bits} drawn, {frame.done}/{frame.total} word "
        f"lengths computed. Reproduce the numbers: {cmds}"
    )
    figs = build_figures(frame)
    if getattr(frame, "datalength", None) is None:  # not computed: no empty "press Compute" plot in the page
        figs.pop("datalength", None)
    return figures_html(figs, f"qsid dashboard: {frame.system.name}", caption)
