"""The summary of a nonlinear plant's frame (:class:`~app.dashboard.frames.KoopmanFrame`), as
:mod:`app.dashboard.summary` is a linear plant's (:class:`~app.dashboard.render.Renderer` draws both).

It states what holds for a nonlinear plant: no linear certificate applies; BCLS's correction is exact
only for a polynomial dictionary with subtractive dither; the large-data limit only where its hypotheses hold.
"""

from __future__ import annotations

from typing import Any

from app.figures.error_vs_bits import limit_note
from qsid_core.studies import NO_CERTIFICATES

__all__ = ["koopman_summary", "bcls_exactness"]


def bcls_exactness(values: Any) -> str:
    """One sentence: whether BCLS's de-biasing is exact for the panel's dictionary and dither."""
    lifting, dither = str(values.lifting).strip(), str(values.dither)
    if lifting.startswith("rbf"):
        return (
            f"BCLS: no exact correction for the radial functions of {lifting} (it falls back to LS); only "
            "polynomial dictionaries with subtractive dither are de-biased exactly."
        )
    if dither != "subtractive":
        return (
            f"BCLS: no exact correction with {dither} dither (the error is not independent uniform noise): the "
            "Bernoulli correction is applied nominally; it is exact only with subtractive dither."
        )
    return (
        f"BCLS: exact de-biasing of every monomial of {lifting} (polynomial dictionary, subtractive dither): the "
        "quantized moments' bias is removed, their spread is not."
    )


def _pm(s: dict[str, float] | None) -> str:
    if not s or s.get("mean") is None or s["mean"] != s["mean"]:
        return "–"
    return f"{s['mean']:.3g} ± {s['std']:.2g}"


def koopman_summary(frame: Any) -> str:
    """The summary text of a nonlinear frame (markdown)."""
    v, b = frame.values, frame.bits
    lines = [
        f"**{frame.system.name}** (nonlinear, Koopman/EDMD), dictionary `{str(v.lifting).strip()}` "
        f"({frame.features} features), {v.trajectories} × {v.steps} samples, {v.realizations} realizations.",
    ]
    parts = []
    for lab in frame.labels:
        r = frame.rows[lab].get(b, {})
        oc = r.get("closed_loop_outcomes")
        off = r.get("settled_offset")
        loops = (
            f", MPC converged {oc['converged']}/{r['realizations']}, "
            f"{r.get('within_radius')}/{r['realizations']} within radius {v.converged_radius:g}"
            + (f", settled offset median {off['median']:.2g}" if off else "")
            if oc
            else ""
        )
        parts.append(f"{lab} {_pm(r.get('err_G'))}{loops}")
    lines.append(f"At b = {b}, error of [A_z, B_z] vs the unquantized EDMD: " + "; ".join(parts) + ".")
    if frame.reference_loop is not None:
        ref = frame.reference_loop
        off = float(ref.settled_offset[0]) if len(ref.settled_offset) else float("nan")
        settled = f", settled offset {off:.2g} (what the dictionary alone leaves)" if off == off else ""
        lines.append(f"The unquantized EDMD's Koopman MPC: {ref.outcome[0]}{settled}.")
    lines.append(bcls_exactness(v))
    if "LS" in frame.labels:  # what the error plot draws, in the plot's own words
        note = limit_note(frame.series(), bool(v.guard))
        lines.append(
            "LS's large-data limit (dashed): "
            + (
                f"not drawn: {note.rstrip('.')}."
                if note
                else "drawn (polynomial dictionary, subtractive dither, no overload)."
            )
        )
    lines.append("Not certified: " + NO_CERTIFICATES + ".")
    if frame.data_report:
        lines.append(frame.data_report + ".")
    return "  \n".join(lines)
