"""``qsid bits``: how many bits does the MPC built from quantized data need?"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from .files import input_files, out_file, write_text
from .output import dumps, g
from .parser import add_run_options
from .runner import UsageError, bits_text, config, executor, system_from_args
from .study import add_nonlinear_options, nonlinear_result, wanted

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run", "format_bits"]

HELP = "how many bits the MPC needs: stabilized share and cost gap per b, three word lengths"
DESCRIPTION = (
    "For each b: the share of MPC loops (built on the quantized-data models) that converge on the true "
    "plant, with a 95 % interval, and the gap of their mean cost to the true-model MPC. Then three word "
    "lengths: b_observed (from which on at least --target of the loops converge and the cost gap, signed "
    "and over the loops that did not diverge, is at most --cost-gap in size), b_robust (from which on the "
    "small-gain test certifies the loops: for Theorem 1's model where the measured model errors are within "
    "25 % of its prediction, or for every loop's own model) and b_letter (from which on the letter's "
    "ultimate bound is below rho and below ||x0||). Without --mpc-steps the loops run for a length chosen "
    "from the plant (until the true-model loop's remaining cost is below 1e-6 of its total), printed."
)


def _fraction(text: str) -> float:
    try:
        v = float(text.strip().rstrip("%")) / (100.0 if text.strip().endswith("%") else 1.0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number like 0.95 or 95%; got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite; got {text!r}")
    return v


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    add_nonlinear_options(p)
    for act in p._actions:  # the loop length is chosen from the plant unless given
        if act.dest == "mpc_steps":
            act.default = None
            act.help = (
                "closed-loop steps on the true system (default: chosen from the plant, until the true-model "
                "loop's remaining cost is below 1e-6 of its total; printed)"
            )
    a = p.add_argument_group("the answer")
    a.add_argument(
        "--target",
        type=_fraction,
        default=0.95,
        metavar="P",
        help="share of stabilized loops b_observed asks for, in (0, 1] or as a percentage (default: 0.95)",
    )
    a.add_argument(
        "--cost-gap",
        type=_fraction,
        default=0.01,
        metavar="G",
        help="largest gap of the mean closed-loop cost to the true-model MPC's, relative, >= 0 "
        "(default: 0.01, i.e. 1%%)",
    )
    a.add_argument("--json", action="store_true", help="print one JSON object to stdout instead of a table")
    a.add_argument(
        "--out",
        metavar="FILE",
        default=None,
        help="also write the JSON to FILE (checked before the run; an existing FILE is replaced)",
    )


def _check(args: argparse.Namespace) -> None:
    if not 0 < args.target <= 1:
        raise UsageError(f"argument --target: must be in (0, 1] (or 0%..100%); got {args.target:g}")
    if not 0 <= args.cost_gap <= 1e6:
        raise UsageError(f"argument --cost-gap: must be >= 0 (a relative gap, 0.01 = 1%); got {args.cost_gap:g}")


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x + 0.0:.1f}%".replace("-0.0%", "0.0%")


def _gap(r: dict) -> str:
    """The signed cost gap, "diverged" when every loop diverged or failed (never a 20-digit number)."""
    x = r["cost_gap"]
    if x is None:
        return "diverged" if r.get("cost_diverged") else "-"
    if abs(x) >= 1e4:  # 1,000,000 % and more: a power of ten reads better than the digits
        return f"{100 * x:+.2g}%"
    if abs(x) >= 10:
        return f"{100 * x:+.0f}%"
    return f"{100 * x + 0.0:+.1f}%".replace("-0.0%", "+0.0%")


def _certificate(r: dict) -> str:
    """The small-gain column: the verdict, then the test for Theorem 1's model."""
    if r["robust_certified"] is None:
        return "-"
    test = f"{g(r['robust_perturbation'], '.2g')}/{g(r['robust_radius'], '.2g')}"
    if r["robust_certified"]:
        return f"yes ({'Thm 1' if r['robust_basis'] == 'theorem1' else 'own'}) {test}"
    hypothesis = "large-data hypothesis fails" in (r.get("robust_note") or "")
    return f"no (hyp.) {test}" if hypothesis else f"no {test}"


def format_bits(d: dict) -> str:
    """The plain table of a ``qsid bits`` JSON dict, the reasons for each b not certified, then the answer."""
    head = [
        "b",
        "stabilized",
        "95% interval",
        "cost gap",
        "converged/bounded/diverged/failed",
        "certified (pert./radius)",
        "certified (own error)",
        "delta",
        "delta < rho",
        "delta < |x0|",
    ]
    rows = []
    for r in d["rows"]:
        oc = r["closed_loop_outcomes"]
        lo, hi = r["stabilized_interval"]
        total = sum(oc.values())
        rows.append(
            [
                str(r["bits"]),
                _pct(r["stabilized_fraction"]),
                f"{_pct(lo)}..{_pct(hi)}",
                _gap(r),
                "/".join(str(oc.get(k, 0)) for k in ("converged", "bounded", "diverged", "failed")),
                _certificate(r),
                "-" if r["robust_certified_realized"] is None else f"{r['robust_certified_realized']}/{total}",
                g(r["ultimate_bound"], ".3g"),
                _yn(r["bound_self_consistent"]),
                _yn(r["bound_informative"]),
            ]
        )
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]

    def fmt(cells: Sequence[str]) -> str:
        return "  ".join(c.rjust(w) for c, w in zip(cells, widths))

    s = d["settings"]
    length = (d.get("loop_length") or {}).get("rule")
    lines = [
        f"system {d['system']}: {s['trajectories']} x {s['steps']} samples, {s['realizations']} realizations, "
        f"estimator {s['estimator']}, dither {s['dither']}; true-model MPC cost {g(d['true_model_cost'], '.4g')}",
        *([f"closed-loop length {length}"] if length else []),
        fmt(head),
        fmt(["-" * w for w in widths]),
        *(fmt(r) for r in rows),
        *(f"b = {r['bits']}: {r['robust_note']}" for r in d["rows"] if r.get("robust_note", "").startswith("not")),
        f"b_observed = {_b(d['b_observed'])}, b_robust = {_b(d['b_robust'])}, b_letter = {_b(d['b_letter'])}",
        d["sentence"],
    ]
    return "\n".join(lines)


def _yn(v: bool | None) -> str:
    return "-" if v is None else ("yes" if v else "no")


def _b(v: int | None) -> str:
    return "none" if v is None else str(v)


def run(args: argparse.Namespace, rep: Reporter) -> int:
    from qsid_core import Experiment, MPCConfig
    from qsid_core.studies import bits_needed

    _check(args)
    auto_length = args.mpc_steps is None
    if auto_length:
        args.mpc_steps = MPCConfig().steps
    if wanted(args):
        return _run_nonlinear(args, rep)
    system = system_from_args(args)
    out = out_file(args.out, rep, inputs=input_files(args))
    cfg = config(args, system, True)
    with executor(args, rep) as (pool, nw):
        ex = Experiment(cfg, pool, tasks=max(4, 2 * nw))
        rep.stage(
            f"system {system.name!r}: b = {bits_text(cfg.bits)}, {cfg.realizations} realizations, "
            f"{cfg.trajectories} x {cfg.steps} samples; quantize, identify, run and judge every closed loop"
        )
        ans = bits_needed(
            cfg,
            target=args.target,
            cost_gap=args.cost_gap,
            executor=pool,
            progress=rep,
            experiment=ex,
            auto_length=auto_length,
        )
    d = ans.to_dict()
    d["timing_s"] = ans.result.timing_s if ans.result is not None else {}
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n", rep)
        rep.stage(f"JSON written to {out}")
    print(text if args.json else format_bits(d))
    return 0


def _run_nonlinear(args: argparse.Namespace, rep: Reporter) -> int:
    """``qsid bits`` for a nonlinear plant: b_observed only (the linear certificates do not apply)."""
    if getattr(args, "no_mpc", False):
        raise UsageError("qsid bits needs the closed loops; drop --no-mpc")
    out = out_file(args.out, rep, inputs=input_files(args))
    d = nonlinear_result(args, rep)
    rows = d["results"]
    ok = [r["stabilized_fraction"] is not None and r["stabilized_fraction"] >= args.target for r in rows]
    b_obs = next((rows[i]["bits"] for i in range(len(rows)) if all(ok[i:])), None)
    answer = {
        "kind": "koopman-bits",
        "system": d["system"],
        "config": d["config"],
        "target": args.target,
        "rows": [
            {"bits": r["bits"], "stabilized_fraction": r["stabilized_fraction"], "outcomes": r["closed_loop_outcomes"]}
            for r in rows
        ],
        "b_observed": b_obs,
        "b_robust": None,
        "b_letter": None,
        "note": d["certificates"],
    }
    text = dumps(answer)
    if out is not None:
        write_text(out, text + "\n", rep)
    if args.json:
        print(text)
        return 0
    print("b  converged")
    for r in rows:
        print(f"{r['bits']:<2} {r['closed_loop_outcomes']['converged']}/{r['realizations']}")
    got = f"b_observed = {b_obs}" if b_obs is not None else "no swept b reaches the target"
    print(f"{got} (at least {100 * args.target:g}% of the loops converge from there on); {d['certificates']}")
    return 0
