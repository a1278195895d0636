"""Output formats of ``qsid``: strict JSON, and the readable sweep table."""

from __future__ import annotations

import enum
import json
import math
from collections.abc import Container, Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from qsid_core import SweepResult

__all__ = ["clean", "dumps", "g", "format_table", "text_table", "sweep_dict", "assumptions_lines"]


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


def sweep_dict(res: SweepResult) -> dict[str, Any]:
    """``res.to_dict()`` with the MPC's resolved settings (x0, x_ref, x_max, Q and R diagonals) in its config."""
    d = res.to_dict()
    mcfg = res.config.mpc
    if mcfg is not None and d["config"].get("mpc") is not None:
        r = mcfg.resolve(res.system)
        d["config"]["mpc"].update(
            clean(
                {
                    "x0": r.x0,
                    "x_ref": r.x_ref,
                    "x_max": r.x_max,
                    "Q": [float(v) for v in r.Q.diagonal()],
                    "R": [float(v) for v in r.R.diagonal()],
                }
            )
        )
    return d


def _bits_list(bits: list) -> str:
    """``[1, 2, 3, 5]`` -> ``"1..3, 5"``."""
    out: list[str] = []
    run: list[int] = []
    for b in bits:
        if run and b == run[-1] + 1:
            run.append(b)
        else:
            if run:
                out.append(f"{run[0]}..{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)))
            run = [b]
    if run:
        out.append(f"{run[0]}..{run[-1]}" if len(run) > 2 else ", ".join(map(str, run)))
    return ", ".join(out)


#: Hypothesis flag in the JSON -> how the table names it when it fails.
_HYPOTHESES = (
    ("known_noise", "dither of known noise variance (subtractive or tpdf)"),
    ("no_overload", "no overload in effect (clipped samples move the estimate by > 1/3 of its fluctuation)"),
    ("stationary", "Psi Psi^T/T converges (no eigenvalue of A on/outside the unit circle)"),
    ("large_data", "large data (Theorem 1's bias above the finite-data fluctuation)"),
    ("sensor_noise_known", "sensor noise known to BCLS (--noise-known; BCLS only)"),
)


def stationary_why(radius: float | None) -> str:
    """Why Theorem 1 does not apply to a plant whose ``A`` has spectral radius ``radius`` >= 1, and which
    plant shows it, in one plain sentence."""
    if radius is not None and abs(radius - 1.0) < 1e-6:
        what = (
            "an eigenvalue on the unit circle (an integrator, like the dc-motor's angle, or an undamped mode): "
            "its samples wander"
        )
    else:
        what = f"an eigenvalue outside the unit circle (spectral radius {g(radius, '.4g')}): its samples grow"
    return (
        f"why: A has {what} instead of settling, so the data are not stationary, Psi Psi^T/T has no limit and "
        "Theorem 1 (a statement about T -> inf) does not apply; a stable plant shows it hold at coarse b: "
        "qsid sweep --system boeing747 (the dashboard's theorem1 lesson)"
    )


def assumptions_lines(results: list) -> list:
    """Plain lines saying which hypotheses of Theorem 1 / BCLS fail at which b (empty if all hold)."""
    rows = [r for r in results if r.get("assumptions")]
    lines = []
    for key, name in _HYPOTHESES:
        bad = [r["bits"] for r in rows if not r["assumptions"].get(key, True)]
        if bad:
            lines.append(f"  fails: {name} at b = {_bits_list(bad)}")
            if key == "stationary":  # the plain reason (the default plant's case), and where to see Theorem 1
                lines.append("    " + stationary_why(rows[0]["assumptions"].get("spectral_radius")))
            if key == "no_overload":  # the engine names the range, the share it clips and what that does
                why = [
                    x
                    for x in rows[[r["bits"] for r in rows].index(bad[-1])]["assumptions"].get("notes", ())
                    if x.startswith("overload:")
                ]
                lines += [f"    at b = {bad[-1]}: {why[0]}"] if why else []
    for k in ("A", "B"):
        kept = [
            r["bits"]
            for r in rows
            if r["assumptions"].get(f"fits_{k}") and not r["assumptions"].get(f"theorem1_holds_{k}", True)
        ]
        if kept:
            lines.append(
                f"  a hypothesis formally fails yet Theorem 1's prediction fits {k} (mean LS error "
                f"within 5 % of the line) at b = {_bits_list(kept)}"
            )
    if lines:
        t1 = [r["bits"] for r in rows if not r["assumptions"]["theorem1_holds"]]
        bc = [r["bits"] for r in rows if not r["assumptions"]["bcls_holds"]]
        head = (
            f"assumptions: Theorem 1's line does not apply at b = {_bits_list(t1) or 'none'}; "
            f"BCLS's correction does not apply at b = {_bits_list(bc) or 'none'}"
        )
        lines.insert(0, head)
    elif rows:
        lines.append("assumptions: every hypothesis of Theorem 1 and BCLS holds at every b")
    return lines


def _flags(r: dict) -> str:
    a = r.get("assumptions")
    if not a:
        return "-"
    t1 = (
        "yes"
        if a["theorem1_holds"]
        else ("A" if a.get("theorem1_holds_A") else "B" if a.get("theorem1_holds_B") else "no")
    )  # one block only
    return f"{t1}/{'yes' if a['bcls_holds'] else 'no'}"


def g(v: float | None, fmt: str = ".3g", none: str = "-") -> str:
    return none if v is None else format(v, fmt)


def _pm(stats: dict | None) -> str:
    if not stats or stats.get("mean") is None:
        return "-"
    return f"{stats['mean']:.3e} +/- {stats['std']:.1e}"


def _limits_text(c: dict) -> str:
    fr = c.get("fixed_range")
    if not fr:
        return ""
    return " " + ";".join(f"[{lo:g}, {hi:g}]" for lo, hi in fr)


def _stabilized(r: dict) -> str:
    """``48/50`` loops judged converged on the true plant ("-" without MPC verdicts)."""
    oc = r.get("closed_loop_outcomes")
    if not oc:
        return "-"
    return f"{oc['converged']}/{sum(oc.values())}"


def real_loop_line(d: dict) -> str:
    """What the residual of a disturbed / quantized-feedback loop comes from, next to the data-rate floor."""
    m = d["config"]["mpc"]
    causes = []
    if m.get("disturbance"):
        causes.append(f"disturbance sigma {m['disturbance']:g} ({m.get('disturbance_kind', 'gaussian')})")
    if m.get("feedback_bits"):
        causes.append(f"feedback quantized to {m['feedback_bits']} bits per state")
    if m.get("feedback_noise"):
        causes.append(f"sensor noise sigma {m['feedback_noise']:g}")
    if m.get("reference"):
        causes.append(
            "the time-varying reference " + (m["reference"] if isinstance(m["reference"], str) else "(samples)")
        )
    text = (
        f"steady err = RMS of |x_t - x_ref| over the last half of each loop; causes: {', '.join(causes)}; "
        f"the true-model loop keeps {g(d.get('steady_state_error_true_model'), '.3e')} (no model error: "
        "that much comes from these causes); delta covers the model error only"
    )
    if m.get("reference"):
        text += (
            f"; tracking err = RMS of |x_t - r_t| over each whole loop, true model "
            f"{g(d.get('tracking_error_true_model'), '.4e')}"
        )
    if m.get("feedback_bits"):
        text += (
            f"; data-rate floor of this plant: {g(d.get('data_rate_bits'), '.3g')} bits per sample "
            "(any quantized feedback needs more)"
        )
    return text


def verdict_lines(results: list) -> list:
    """One line per b where some closed loop did not converge: how many stayed bounded, diverged, failed."""
    out = []
    for r in results:
        oc = r.get("closed_loop_outcomes") or {}
        total = sum(oc.values())
        if not oc or oc["converged"] == total:
            continue
        parts = [f"{oc[k]} {k}" for k in ("bounded", "diverged", "failed") if oc.get(k)]
        rad = (r.get("closed_loop_spectral_radius") or {}).get("max")
        out.append(
            f"b = {r['bits']}: {total - oc['converged']} of {total} closed loops did not converge "
            f"({', '.join(parts)}; spectral radius of A - B K^ up to {g(rad, '.4f')})"
        )
    return out


def bound_lines(results: list) -> list:
    """Where the letter's delta says nothing: delta >= rho (its proof does not apply) or delta >= ||x0||."""
    bad = [r["bits"] for r in results if r.get("bound_self_consistent") is False]
    weak = [r["bits"] for r in results if r.get("bound_self_consistent") and r.get("bound_informative") is False]
    out = []
    if bad:
        out.append(
            f"* delta >= rho at b = {_bits_list(bad)}: the proof assumes the state stays within rho, "
            "so there it gives no bound"
        )
    if weak:
        out.append(f"delta >= ||x0|| at b = {_bits_list(weak)}: a bound, but larger than the start")
    return out


def _what_if_lines(c: dict) -> list:
    """Word length per channel and sensor noise, when set (one line; nothing for the letter's setting)."""
    parts = []
    ib = c.get("input_bits")
    if ib is not None:
        which = (
            "exact (inputs not quantized: eps_u = 0)"
            if ib == "exact"
            else ",".join(map(str, ib))
            if isinstance(ib, list)
            else str(ib)
        )
        parts.append(f"b is swept for the states; input bits {which}")
    sb = c.get("state_bits")
    if sb is not None:
        parts.append(f"state bits {','.join(map(str, sb))} (b = the swept word length)")
    noise = c.get("noise") or []
    if any(v for v in noise):
        parts.append(
            f"sensor noise sigma {','.join(format(v, 'g') for v in noise)} on the states"
            + (
                " (known to BCLS: D + sigma^2)"
                if c.get("noise_known")
                else " (unknown to BCLS: it corrects only the quantization noise)"
            )
        )
    return ["; ".join(parts)] if parts else []


def _table_row(r: dict[str, Any], noisy: bool, tracking: bool) -> list[str]:
    """The cells of one b's row of :func:`format_table`."""
    eps = list(r["eps_x"]) + list(r["eps_u"])
    cost = r.get("mpc_cost")
    cost_s = "-" if cost is None else f"{g(cost.get('mean'), '.4g')} ({cost.get('failed', 0)})"
    fsn = r.get("final_state_norm")
    row = [
        str(r["bits"]),
        f"{min(eps):.2e}..{max(eps):.2e}",
        _pm(r["err_A"]),
        g(r["err_A_theory"], ".3e"),
        _pm(r["err_B"]),
        g(r["err_B_theory"], ".3e"),
        f"{100 * r['overload_fraction']:.2f}%",
        cost_s,
        _stabilized(r),
        g(r["ultimate_bound"], ".3e") + ("" if r.get("bound_self_consistent") is not False else "*"),
        "-" if fsn is None else g(fsn.get("mean"), ".2e"),
        _flags(r),
    ]
    if noisy:
        row.insert(10, g((r.get("steady_state_error") or {}).get("mean"), ".3e"))
    if tracking:
        row.insert(10, g((r.get("tracking_error") or {}).get("mean"), ".4e"))
    return row


def _settings_line(system: str, c: dict[str, Any]) -> str:
    """The first line of :func:`format_table`: the sweep's settings."""
    return (
        f"system {system}: {c['trajectories']} x {c['steps']} samples, {c['realizations']} realizations, "
        f"range {c['range']}{_limits_text(c)}{' + guard' if c['guard'] else ', no guard'}, "
        f"inputs U[-{c.get('input_amplitude', 1):g}, {c.get('input_amplitude', 1):g}], dither {c['dither']}, estimator {c['estimator']}"
        + (
            ""
            if c["mpc"] is None
            else f", MPC horizon {c['mpc']['horizon']}, {c['mpc']['steps']} steps, u_max "
            f"{','.join(format(u, 'g') for u in c['mpc']['u_max'])}"
        )
    )


def _closing_lines(d: dict[str, Any], c: dict[str, Any], noisy: bool) -> list[str]:
    """The lines under the table: MPC failures, the noisy loop, verdicts, bounds, assumptions, BCLS."""
    lines: list[str] = []
    fails: dict[str, int] = {}
    for r in d["results"]:
        for kind, k in ((r.get("mpc_cost") or {}).get("failures") or {}).items():
            fails[kind] = fails.get(kind, 0) + k
    if fails:
        lines.append("MPC failures by kind: " + ", ".join(f"{k} {v}" for k, v in sorted(fails.items())))
    if noisy:
        lines.append(real_loop_line(d))
    lines.extend(verdict_lines(d["results"]))
    lines.extend(bound_lines(d["results"]))
    lines.extend(assumptions_lines(d["results"]))
    bc = d.get("bcls") or {}
    if bc.get("reason"):
        lines.append(
            f"BCLS not applicable with {c.get('dither')} dither: {bc['reason']}"
            + ("; BCLS used a nominal D = eps^2/12" if c.get("estimator") == "bcls" else "")
        )
    fb = sum(r.get("bcls_fallbacks", 0) for r in d["results"])
    if fb:
        lines.append(f"BCLS fell back to LS in {fb} realization(s) (corrected Gram matrix not positive definite)")
    return lines


def text_table(head: Sequence[str], rows: Sequence[Sequence[str]], left: Container[int] = ()) -> list[str]:
    """The lines of a plain-text table: the header, a dashed rule, the rows; every column as wide as its widest
    cell, right-aligned (the columns ``left``: left-aligned), two spaces apart.

    Hand-written rather than rich.Table: this exact plain-text layout is the documented, diff-able stdout of
    the linear and the nonlinear sweep alike."""
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(head)]

    def fmt(cells: Sequence[str]) -> str:
        return "  ".join(c.ljust(w) if i in left else c.rjust(w) for i, (c, w) in enumerate(zip(cells, widths)))

    return [fmt(head), fmt(["-" * w for w in widths]), *(fmt(row) for row in rows)]


def format_table(d: dict) -> str:
    """The readable table of a sweep dict (``SweepResult.to_dict()``)."""
    head = [
        "b",
        "eps min..max",
        "err_A mean +/- std",
        "Thm1 A",
        "err_B mean +/- std",
        "Thm1 B",
        "overload",
        "MPC cost (failed)",
        "stabilized",
        "delta bound",
        "|x_T| mean",
        "Thm1/BCLS hold",
    ]
    m = d["config"].get("mpc") or {}
    noisy = bool(m.get("disturbance") or m.get("feedback_bits") or m.get("feedback_noise") or m.get("reference"))
    if noisy:
        head.insert(10, "steady err")
    if m.get("reference"):
        head.insert(10, "tracking err")
    rows = [_table_row(r, noisy, bool(m.get("reference"))) for r in d["results"]]
    c = d["config"]
    lines = [_settings_line(d["system"], c), *_what_if_lines(c), *text_table(head, rows, left={1})]
    t = d.get("timing_s", {})
    slope = (
        f"slope of log10 mean error per bit: A {g(d.get('slope_A'), '+.3f')}, "
        f"B {g(d.get('slope_B'), '+.3f')} (letter: -0.301 = -log10 2)"
    )
    true_cost = "MPC off" if c["mpc"] is None else f"true-model MPC cost {g(d.get('mpc_cost_true_model'), '.4g')}"
    timing = "time " + ", ".join(f"{k} {v:.2f} s" for k, v in t.items())
    lines.append(f"{slope}; {true_cost}; {timing}")
    lines += _closing_lines(d, c, noisy)
    return "\n".join(lines)
