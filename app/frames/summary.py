"""The numeric summary of a frame at the current b (markdown), for a linear and a nonlinear plant alike.

A linear plant's: eps per channel, errors, overload, bounds, hypotheses, failures (its closed-loop lines:
:mod:`app.frames.loop_lines`). A nonlinear plant's states what holds for it: no linear certificate applies;
BCLS's correction is exact only for a polynomial dictionary with subtractive dither; the large-data limit only
where its hypotheses hold.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from app.figures.error_vs_bits import limit_note
from app.figures.hypotheses import bcls_reasons, fits_reasons, line_holds, theorem1_reasons
from qsid_core.studies import NO_CERTIFICATES, OVERLOAD_EFFECT_RATIO

from .frame import Frame, KoopmanFrame, lifted
from .loop_lines import (
    bound_lesson_lines,
    bounds_line,
    certificate_lines,
    failures_text,
    fmt,
    real_loop_lines,
    saturation_line,
)

if TYPE_CHECKING:
    from app.settings.values import Values

__all__ = ["summary_markdown", "bcls_exactness"]


def _overload(first: dict[str, Any]) -> str:
    """The share of overloaded samples and, from the engine, whether its predicted effect on the estimate matters."""
    a = first.get("assumptions") or {}
    head = f"overload: {100 * first['overload_fraction']:.2f} % of samples"
    if "overload_effect_A" not in a:
        return head
    eff = (
        f"predicted effect of the clipped samples on Â {fmt(a['overload_effect_A'])}, on B̂ "
        f"{fmt(a['overload_effect_B'])} (finite-data fluctuation {fmt(a['fluctuation_A'])}, "
        f"{fmt(a['fluctuation_B'])})"
    )
    verdict = (
        f"harmless here (below 1/{OVERLOAD_EFFECT_RATIO:g} of the fluctuation)"
        if a["no_overload"]
        else "it matters (see Theorem 1 / BCLS below)"
    )
    return f"{head} clipped by {a.get('overload_range', 'the range')}; {eff}: {verdict}"


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


def _lesson_changes(values: Values) -> list[str]:
    """A line when a lesson is open but settings its claims depend on were changed since (its text describes
    its own settings; the same drift as the mark above the text, :func:`app.lessons.drift.lesson_drift`)."""
    from app.lessons.drift import drift_label, lesson_drift
    from app.lessons.table import NONE

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
        bounds_line(frame, first),
        "",
        *bound_lesson_lines(frame, first),
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
            f"| {lab} | {fmt(r['err_A']['mean'])} | {fmt(r['err_B']['mean'])} | {fmt(cost, '.4g')} | "
            f"{failures_text(r, frame.loops[lab])} |"
        )
    lines.append(f"| Thm 1 | {fmt(first['err_A_theory'])} | {fmt(first['err_B_theory'])} | | |")
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


def _mean_std(s: dict[str, float] | None) -> str:
    if not s or s.get("mean") is None or s["mean"] != s["mean"]:
        return "–"
    return f"{s['mean']:.3g} ± {s['std']:.2g}"


def _lifted_summary(frame: KoopmanFrame) -> str:
    """The summary text of a nonlinear plant's frame (markdown): no linear certificate applies; BCLS's correction is
    exact only for a polynomial dictionary with subtractive dither; the large-data limit only where its hypotheses
    hold."""
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
        parts.append(f"{lab} {_mean_std(r.get('err_G'))}{loops}")
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


def summary_markdown(frame: Frame | KoopmanFrame) -> str:
    """The numeric summary at the current b (markdown), chosen by what the frame's result holds: eps per channel,
    errors, overload, bounds and failures of a linear plant; the lifted models' errors and loops of a nonlinear one."""
    if lifted(frame):
        assert isinstance(frame, KoopmanFrame)
        return _lifted_summary(frame)
    assert isinstance(frame, Frame)
    first = frame.rows[frame.labels[0]][frame.bits]
    lines = _header(frame, first) + _error_table(frame, first)
    lines += ["", saturation_line(frame), ""]
    tl = frame.true_loop
    why = f" (its MPC failed: {tl.messages[0]})" if tl is not None and tl.failure and tl.failure[0] else ""
    lines.append(f"MPC cost with the true model: {fmt(frame.true_cost, '.4g')}{why}")
    lines += certificate_lines(frame)
    lines += real_loop_lines(frame)
    lines += _notes(frame)
    return "\n".join(lines)
