"""The numeric summary of a tab at the current b (markdown): eps per channel, errors, overload, failures."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from app.figures.hypotheses import CAPTION, bcls_reasons, fits_reasons, line_holds, theorem1_reasons
from qsid_core.control import saturated_steps
from qsid_core.studies import OVERLOAD_EFFECT_RATIO

from .frames import Frame
from .settings import LABELS

if TYPE_CHECKING:
    from qsid_core import ClosedLoops

    from .settings import Values

__all__ = ["summary_markdown"]


def _g(x: float | None, fmt: str = ".3g") -> str:
    return "–" if x is None else format(x, fmt)


def _failures(row: dict[str, Any], lp: ClosedLoops) -> str:
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


def _real_loop(frame: Frame) -> list[str]:
    """With a disturbance or a quantized/noisy measurement: the residual per estimator and the true model's."""
    from app.figures.residual import causes_text
    from qsid_core.control import data_rate_bits

    mc = frame.ex.config.mpc if frame.ex is not None else None
    causes = causes_text(mc)
    out: list[str] = []
    if mc is not None and mc.reference is not None and frame.true_loop is not None:
        per = " · ".join(
            f"{lab} {_g((frame.rows[lab][frame.bits].get('tracking_error') or {}).get('mean'))}" for lab in frame.labels
        )
        out += [
            "",
            f"**Tracking** {mc.reference if isinstance(mc.reference, str) else 'sampled reference'}: "
            f"RMS ‖x_t − r_t‖ {per} · true model {_g(float(frame.true_loop.tracking_error[0]))} "
            "(δ(ε) assumes regulation to 0; the verdicts judge the same MPC regulating to 0)",
        ]
    if not causes or frame.true_loop is None or mc is None:
        return out
    per = " · ".join(
        f"{lab} {_g((frame.rows[lab][frame.bits].get('steady_state_error') or {}).get('mean'))}" for lab in frame.labels
    )
    true_err = float(frame.true_loop.steady_state_error[0])
    text = (
        f"**Real loop** ({causes}): steady-state error {per} · true model {_g(true_err)} — no model error there: "
        "that much comes from the causes named here; δ(ε) covers the model error only."
    )
    if mc.feedback_bits is not None:
        text += (
            f" Data-rate floor of this plant: {data_rate_bits(frame.system.A):.3g} bits per sample "
            f"(the loop sends {mc.feedback_bits} × {frame.system.n} = {mc.feedback_bits * frame.system.n})."
        )
    return out + ["", text]


def _bounds(frame: Frame, first: dict[str, Any]) -> str:
    """The two ultimate bounds at the current b, the rho they used, and what they mean."""
    rho = first.get("rho")
    rho_text = f"ρ = {_g(rho)} ({'automatic' if frame.values.rho_auto else 'set in the panel'})"
    x0n = float(np.linalg.norm(frame.x0))
    verdict = ""
    if first.get("bound_self_consistent") is False:
        verdict = " — **not a bound here**: δ ≥ ρ, and the proof assumes the state stays within ρ"
    elif first.get("bound_informative") is False:
        verdict = f" — δ ≥ ‖x0‖ = {x0n:.3g}: larger than the start"
    parts = [f"letter's δ(ε) = {_g(first['ultimate_bound'])} (Theorem 1's T → ∞ model errors){verdict}"]
    for lab in frame.labels:
        rb = frame.rows[lab][frame.bits].get("ultimate_bound_realized") or {}
        sc = rb.get("self_consistent")
        ok = "" if sc is None else f", below its ρ in {sc}/{frame.values.realizations}"
        parts.append(
            f"a-posteriori δ {lab} = {_g(rb.get('median'))} median, {_g(rb.get('max'))} max "
            f"(each realization's own model error and P{ok})"
        )
    return "**Ultimate bound** · " + " · ".join(parts) + f" · {rho_text}.  \n*{CAPTION}.*"


def _overload(first: dict[str, Any]) -> str:
    """The share of overloaded samples and, from the engine, whether its predicted effect on the estimate matters."""
    a = first.get("assumptions") or {}
    head = f"overload: {100 * first['overload_fraction']:.2f} % of samples"
    if "overload_effect_A" not in a:
        return head
    eff = (
        f"predicted effect of the clipped samples on Â {_g(a['overload_effect_A'])}, on B̂ "
        f"{_g(a['overload_effect_B'])} (finite-data fluctuation {_g(a['fluctuation_A'])}, "
        f"{_g(a['fluctuation_B'])})"
    )
    verdict = (
        f"harmless here (below 1/{OVERLOAD_EFFECT_RATIO:g} of the fluctuation)"
        if a["no_overload"]
        else "it matters (see Theorem 1 / BCLS below)"
    )
    return f"{head} clipped by {a.get('overload_range', 'the range')}; {eff}: {verdict}"


def _bound_lesson(frame: Frame, first: dict[str, Any]) -> list[str]:
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
            f"the loops converge (‖x_T‖ ≤ {_g(xt)}, zero up to rounding): without disturbances there is no "
            "residual, so each δ is loose by its whole size"
        )
    else:
        loose = "; ".join(
            f"{nm} = {_g(d)} is {d / xt:.3g}× the measured max ‖x_T‖ = {_g(xt)}" for nm, d in deltas if d is not None
        )
    rho = first.get("rho")
    d0 = first.get("ultimate_bound")
    checks = []
    if d0 is not None and rho is not None:
        checks.append(
            f"δ {'<' if d0 < rho else '≥'} ρ = {_g(rho)}" + ("" if d0 < rho else " (the proof gives no bound here)")
        )
    if d0 is not None:
        checks.append(f"δ {'<' if d0 < x0n else '≥'} ‖x0‖ = {x0n:.3g}")
    return [f"**Bound lesson, b = {frame.bits}**: {loose}. " + "; ".join(checks) + ".", ""]


def _hypotheses(frame: Frame) -> list[str]:
    """Which hypotheses of Theorem 1 and BCLS fail at the current b, and why (the engine's flags)."""
    b = frame.bits
    first = frame.rows[frame.labels[0]][b]
    a = first.get("assumptions")
    if not a:
        return []
    t1 = theorem1_reasons([first])
    bc = bcls_reasons([first])
    fits = fits_reasons([first])
    on = [k for k in ("A", "B") if line_holds(first, k)]
    if not t1 and not fits:
        head = "all hypotheses hold."
    elif len(on) == 2:
        head = "the line applies (dashed):"
    elif on:
        head = f"the line applies for {'Â' if on == ['A'] else 'B̂'} only (dashed there, faded for the other):"
    else:
        head = "does not apply here (line faded):"
    lines = ["**Theorem 1** (dashed line): " + head]
    lines += [f"- {w}" for w in t1 + fits]
    lines += [
        "",
        "**BCLS** (known noise ε²/12): " + ("its hypotheses hold." if not bc else "its hypotheses fail (✕ marks):"),
    ]
    lines += [f"- {w}" for w in bc]
    return lines


def _saturation(frame: Frame) -> str:
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


def _lesson_changes(values: Values) -> list[str]:
    """A line when a lesson is open but settings its claims depend on were changed since (its text describes
    its own settings; the same drift as the mark above the text, :func:`app.dashboard.lessons.lesson_drift`)."""
    from .lesson_mark import lesson_drift
    from .lessons import NONE, drift_label

    name = getattr(values, "lesson", NONE)
    if not name or name == NONE:
        return []
    changed = lesson_drift(name, values)
    if not changed:
        return []
    return [
        f"*Lesson **{name}** with changed settings ({', '.join(drift_label(k) for k in changed)}): its text "
        "describes its own settings.*",
        "",
    ]


def _certificate(frame: Frame) -> list[str]:
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


def _header(frame: Frame, first: dict) -> list[str]:
    """The summary's first lines: the system, b and data size, eps per channel, overload, bounds, hypotheses."""
    sysm = frame.system
    eps_x = ", ".join(f"{nm} {e:.3g}" for nm, e in zip(sysm.state_names, first["eps_x"]))
    eps_u = ", ".join(f"{nm} {e:.3g}" for nm, e in zip(sysm.input_names, first["eps_u"]))
    eff = first.get("effective_realizations") or frame.values.realizations
    distinct = "" if eff == frame.values.realizations else f" ({eff} distinct: no dither, all identical)"
    return [
        *_lesson_changes(frame.values),
        f"**{sysm.name}**, b = **{frame.bits}** bits, {frame.values.realizations} dither realizations{distinct}, "
        f"{frame.values.trajectories} × {frame.values.steps} samples",
        "",
        f"ε states: {eps_x}  ",
        f"ε inputs: {eps_u}  ",
        _overload(first),
        "",
        _bounds(frame, first),
        "",
        *_bound_lesson(frame, first),
        *_hypotheses(frame),
        "",
    ]


def _error_table(frame: Frame, first: dict) -> list[str]:
    """One table row per estimator at the current b (errors, MPC cost, closed loops), then Theorem 1's."""
    lines = [
        "| | ‖ΔA‖/‖A‖ | ‖ΔB‖/‖B‖ | MPC cost (loops not diverged) | closed loops on the true plant |",
        "|---|---|---|---|---|",
    ]
    for lab in frame.labels:
        r = frame.rows[lab][frame.bits]
        mc = r.get("mpc_cost") or {}
        cost = mc.get("mean_bounded", mc.get("mean"))  # a diverged loop's cost is no cost
        lines.append(
            f"| {lab} | {_g(r['err_A']['mean'])} | {_g(r['err_B']['mean'])} | {_g(cost, '.4g')} | "
            f"{_failures(r, frame.loops[lab])} |"
        )
    lines.append(f"| Thm 1 | {_g(first['err_A_theory'])} | {_g(first['err_B_theory'])} | | |")
    return lines


def _estimator_notes(frame: Frame) -> list[str]:
    """What went wrong per estimator at the current b: failed identifications, uncontrollable models, BCLS
    falling back to LS, the MPC's messages."""
    b, n = frame.bits, frame.values.realizations
    notes = []
    for lab in frame.labels:
        k = frame.rows[lab][b].get("ident_failures") or 0
        if k:
            why = "; ".join(x for x in frame.idents[lab].notes if x.startswith("identification failed"))[:200]
            notes.append(f"{lab} identification failed in {k} of {n} realizations (their loops are not drawn): {why}")
    for lab in frame.labels:
        k = (frame.rows[lab][b].get("controllability") or {}).get("uncontrollable") or 0
        if k:
            notes.append(
                f"{lab}: {k} of {n} identified models are not controllable (the letter's Assumption 2 fails for them)"
            )
    if "BCLS" in frame.labels:
        r = frame.rows["BCLS"][b]
        if r["bcls_fallbacks"]:
            why = "; ".join(frame.idents["BCLS"].notes[:2])
            notes.append(f"BCLS fell back to LS in {r['bcls_fallbacks']} of {n} realizations: {why}")
    for lab in frame.labels:
        msgs = sorted({m for m in frame.loops[lab].messages if m})
        if msgs:
            notes.append(f"{lab} MPC: " + "; ".join(msgs[:2]) + (" …" if len(msgs) > 2 else ""))
    return notes


def _notes(frame: Frame) -> list[str]:
    """The frame's notes, the estimators' and the views' assumptions (tracking, the bound), as a list."""
    notes = list(frame.notes) + _estimator_notes(frame)
    mpc = frame.ex.config.mpc if frame.ex is not None else None
    if frame.values.x_ref.strip() and mpc is not None and any(float(x) for x in mpc.x_ref or ()):
        notes.append(
            "tracking x_ref ≠ 0: δ(ε) and the bound sphere assume x_ref = 0 (regulation); the loops "
            "settle near x_ref instead"
        )
    if frame.theory.bound_note:
        notes.append(f"bound: {frame.theory.bound_note}")
    return ["", *(f"- {x}" for x in notes)] if notes else []


def summary_markdown(frame: Frame) -> str:
    """The numeric summary at the current b: eps per channel, errors, overload, failures."""
    first = frame.rows[frame.labels[0]][frame.bits]
    lines = _header(frame, first) + _error_table(frame, first)
    lines += ["", _saturation(frame), ""]
    tl = frame.true_loop
    why = f" (its MPC failed: {tl.messages[0]})" if tl is not None and tl.failure and tl.failure[0] else ""
    lines.append(f"MPC cost with the true model: {_g(frame.true_cost, '.4g')}{why}")
    lines += _certificate(frame)
    lines += _real_loop(frame)
    lines += _notes(frame)
    return "\n".join(lines)
