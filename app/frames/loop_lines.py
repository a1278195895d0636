"""The closed-loop lines of a linear plant's summary (:func:`app.frames.summary.summary_markdown`): how the loops
ended on the true plant, the real loop's residual and tracking, the two ultimate bounds (and the bound lesson's
reading of them), saturated inputs and the small-gain certificate."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from app.figures.hypotheses import CAPTION
from app.settings.values import LABELS
from qsid_core.control import saturated_steps

if TYPE_CHECKING:
    from qsid_core import ClosedLoops

    from .frame import Frame

__all__ = [
    "fmt",
    "failures_text",
    "real_loop_lines",
    "bounds_line",
    "bound_lesson_lines",
    "saturation_line",
    "certificate_lines",
]


def fmt(x: float | None, spec: str = ".3g") -> str:
    """A number as the summary writes it ("–" for none)."""
    return "–" if x is None else format(x, spec)


def failures_text(row: dict[str, Any], lp: ClosedLoops) -> str:
    """How the closed loops ended on the true plant: all converged, or the counts of each verdict."""
    mc = row.get("mpc_cost") or {}
    oc = row.get("closed_loop_outcomes") or {}
    total = len(lp.failure)
    if oc:
        if oc["converged"] == total:
            return f"all {total} converged"
        parts = [f"{oc[k]} {k}" for k in ("converged", "bounded", "diverged", "failed") if oc.get(k)]
        rad = (row.get("closed_loop_spectral_radius") or {}).get("max")
        text = f"**{total - oc['converged']}/{total} did not converge**: " + ", ".join(parts)
        return text + (f" (ρ(A − BK̂) up to {rad:.4f})" if rad is not None and rad >= 1 else "")
    k = mc.get("failed", 0)
    if not k:
        return "none failed (not judged)"
    kinds = ", ".join(f"{n} {kind}" for kind, n in sorted(mc.get("failures", {}).items()))
    return f"{k}/{total} ({kinds})"


def real_loop_lines(frame: Frame) -> list[str]:
    """With a disturbance or a quantized/noisy measurement: the residual per estimator and the true model's."""
    from app.figures.residual import causes_text
    from qsid_core.control import data_rate_bits

    mc = frame.ex.config.mpc if frame.ex is not None else None
    causes = causes_text(mc)
    out: list[str] = []
    if mc is not None and mc.reference is not None and frame.true_loop is not None:
        per = " · ".join(
            f"{lab} {fmt((frame.rows[lab][frame.bits].get('tracking_error') or {}).get('mean'))}"
            for lab in frame.labels
        )
        out += [
            "",
            f"**Tracking** {mc.reference if isinstance(mc.reference, str) else 'sampled reference'}: "
            f"RMS ‖x_t − r_t‖ {per} · true model {fmt(float(frame.true_loop.tracking_error[0]))} "
            "(δ(ε) assumes regulation to 0; the verdicts judge the same MPC regulating to 0)",
        ]
    if not causes or frame.true_loop is None or mc is None:
        return out
    per = " · ".join(
        f"{lab} {fmt((frame.rows[lab][frame.bits].get('steady_state_error') or {}).get('mean'))}"
        for lab in frame.labels
    )
    true_err = float(frame.true_loop.steady_state_error[0])
    text = (
        f"**Real loop** ({causes}): steady-state error {per} · true model {fmt(true_err)} — no model error there: "
        "that much comes from the causes named here; δ(ε) covers the model error only."
    )
    if mc.feedback_bits is not None:
        text += (
            f" Data-rate floor of this plant: {data_rate_bits(frame.system.A):.3g} bits per sample "
            f"(the loop sends {mc.feedback_bits} × {frame.system.n} = {mc.feedback_bits * frame.system.n})."
        )
    return out + ["", text]


def bounds_line(frame: Frame, first: dict[str, Any]) -> str:
    """The two ultimate bounds at the current b, the rho they used, and what they mean."""
    rho = first.get("rho")
    rho_text = f"ρ = {fmt(rho)} ({'automatic' if frame.values.rho_auto else 'set in the panel'})"
    x0n = float(np.linalg.norm(frame.x0))
    verdict = ""
    if first.get("bound_self_consistent") is False:
        verdict = " — **not a bound here**: δ ≥ ρ, and the proof assumes the state stays within ρ"
    elif first.get("bound_informative") is False:
        verdict = f" — δ ≥ ‖x0‖ = {x0n:.3g}: larger than the start"
    parts = [f"letter's δ(ε) = {fmt(first['ultimate_bound'])} (Theorem 1's T → ∞ model errors){verdict}"]
    for lab in frame.labels:
        rb = frame.rows[lab][frame.bits].get("ultimate_bound_realized") or {}
        sc = rb.get("self_consistent")
        ok = "" if sc is None else f", below its ρ in {sc}/{frame.values.realizations}"
        parts.append(
            f"a-posteriori δ {lab} = {fmt(rb.get('median'))} median, {fmt(rb.get('max'))} max "
            f"(each realization's own model error and P{ok})"
        )
    return "**Ultimate bound** · " + " · ".join(parts) + f" · {rho_text}.  \n*{CAPTION}.*"


def bound_lesson_lines(frame: Frame, first: dict[str, Any]) -> list[str]:
    """The bound lesson's reading at the current b: how loose each δ is against the measured ‖x_T‖, δ vs ρ and ‖x0‖."""
    from qsid_core.control import CONVERGED_REL_FLOOR

    if getattr(frame.values, "lesson", "") != "bound":
        return []
    x0n = float(np.linalg.norm(frame.x0))
    xt = (first.get("final_state_norm") or {}).get("max")
    deltas = [("letter's δ", first.get("ultimate_bound"))]
    deltas += [
        (
            f"a-posteriori δ {lab} (median)",
            (frame.rows[lab][frame.bits].get("ultimate_bound_realized") or {}).get("median"),
        )
        for lab in frame.labels
    ]
    if xt is None:
        loose = "no closed loops to compare with"
    elif xt <= CONVERGED_REL_FLOOR * max(x0n, 1e-300):
        loose = (
            f"the loops converge (‖x_T‖ ≤ {fmt(xt)}, zero up to rounding): without disturbances there is no "
            "residual, so each δ is loose by its whole size"
        )
    else:
        loose = "; ".join(
            f"{nm} = {fmt(d)} is {d / xt:.3g}× the measured max ‖x_T‖ = {fmt(xt)}" for nm, d in deltas if d is not None
        )
    rho = first.get("rho")
    d0 = first.get("ultimate_bound")
    checks = []
    if d0 is not None and rho is not None:
        checks.append(
            f"δ {'<' if d0 < rho else '≥'} ρ = {fmt(rho)}" + ("" if d0 < rho else " (the proof gives no bound here)")
        )
    if d0 is not None:
        checks.append(f"δ {'<' if d0 < x0n else '≥'} ‖x0‖ = {x0n:.3g}")
    return [f"**Bound lesson, b = {frame.bits}**: {loose}. " + "; ".join(checks) + ".", ""]


def saturation_line(frame: Frame) -> str:
    """Closed-loop steps with an input on its bound, per estimator (and the true-model loop)."""
    mpc = frame.ex.config.mpc if frame.ex is not None else None
    if mpc is None:
        return ""
    u_max = mpc.resolve(frame.system).u_max
    loops = {lab: frame.loops[lab] for lab in frame.labels}
    if frame.true_loop is not None:
        loops["true model"] = frame.true_loop
    parts = []
    for lab, lp in loops.items():
        k, j = saturated_steps(lp.inputs, u_max)
        parts.append(f"{lab} {k} steps in {j}/{len(lp.inputs)} loops")
    return "saturated inputs (|u| at its bound): " + ", ".join(parts)


def certificate_lines(frame: Frame) -> list[str]:
    """Whether the small-gain test certifies the loops at the current b, and why not (qsid bits' rule)."""
    from qsid_core.studies import certificate, certified_own_models, predicted_small_gain

    if frame.ex is None or frame.ex.config.mpc is None:
        return []
    out = []
    pert, rad = predicted_small_gain(frame.ex, frame.bits)
    engine = {label: est for est, label in LABELS.items()}
    for lab in frame.labels:
        r, lp = frame.rows[lab][frame.bits], frame.loops[lab]
        # (frame.loops and frame.idents are the cache's: counted once per b and estimator, the bits view's count)
        own = certified_own_models(frame.ex, frame.bits, engine[lab])
        _, _, note = certificate(r, pert, rad, own, len(lp.cost))
        out.append(f"**Small-gain certificate**, {lab}: {note}.")
    return ["", "  \n".join(out)]
