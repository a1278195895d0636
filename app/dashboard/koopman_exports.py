"""The exports of a tab showing a nonlinear plant: its ``qsid sweep`` lines (one per estimator), its curves as CSV
and JSON (the rows of ``qsid sweep --json``'s ``results``) and its figures as one offline page."""

from __future__ import annotations

import csv
import dataclasses
import html
import io
import math
from typing import Any

from app.settings.command import sweep_command as koopman_command

from .koopman_settings import koopman_config

__all__ = ["koopman_lines", "koopman_rows", "koopman_csv", "koopman_json_data", "koopman_caption"]

_COLUMNS = (
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


def koopman_lines(v: Any) -> list[str]:
    """``qsid sweep`` lines reproducing the panel's numbers, one per estimator shown."""
    cfg, ests = koopman_config(v)
    return [koopman_command(dataclasses.replace(cfg, estimator=e)) for e in ests]


def koopman_rows(frame: Any) -> list[dict[str, Any]]:
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


def koopman_csv(frame: Any) -> str:
    """The curves as CSV (empty cells for missing values)."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=_COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in koopman_rows(frame):
        w.writerow({k: "" if x is None or (isinstance(x, float) and not math.isfinite(x)) else x for k, x in r.items()})
    return buf.getvalue()


def koopman_json_data(frame: Any) -> dict[str, Any]:
    """The curves, settings and command lines (rows as ``qsid sweep --json``'s ``results``)."""
    return {
        "kind": "koopman",
        "system": frame.system.name,
        "settings": dataclasses.asdict(frame.values),
        "command": koopman_lines(frame.values),
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


def koopman_caption(frame: Any) -> str:
    """The offline page's caption of a nonlinear frame, with the command lines (HTML)."""
    cmds = "<br>".join(f"<code>{html.escape(c)}</code>" for c in koopman_lines(frame.values))
    return (
        f"Nonlinear plant {html.escape(frame.system.name)}, b = {frame.bits} drawn, {frame.done}/{frame.total} word "
        f"lengths with loops. Reproduce the numbers: {cmds}"
    )
