"""Nonlinear plants on the command line: ``qsid sweep`` and ``qsid bits`` with ``--lifting`` (Koopman/EDMD).

A nonlinear ``--system`` (a preset of ``qsid systems`` or a plant file naming a ``vector_field``) runs
:func:`qsid_core.studies.run_koopman_sweep` instead of the linear sweep. Where an option is not typed,
the nonlinear defaults apply: 2000 runs x 100 steps, 20 realizations, b = 2..8, MPC
horizon 20 and 200 closed-loop steps (``KoopmanConfig()``, ``KOOPMAN_MPC``); the JSON states what ran.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from .files import input_files, out_file, write_text
from .output import dumps, g
from .runner import UsageError

if TYPE_CHECKING:
    from qsid_core.studies import KoopmanConfig

    from .runner import Reporter

__all__ = ["add_lifting_option", "format_koopman", "koopman_config", "run_bits", "run_sweep", "wanted"]


def add_lifting_option(p: argparse.ArgumentParser) -> None:
    """``--lifting``: the dictionary of a nonlinear plant (default ``poly:3``)."""
    p.add_argument(
        "--lifting",
        default=None,
        metavar="SPEC",
        help="dictionary of observables for a nonlinear --system (Koopman/EDMD): poly:D (monomials up to "
        "total degree D), rbf:K[:thin-plate|gauss] (K radial functions plus the state) or identity "
        "(default for a nonlinear plant: poly:3)",
    )


def wanted(args: argparse.Namespace) -> bool:
    """Whether the run is a nonlinear one (a nonlinear ``--system``); ``--lifting`` on a linear plant is an error."""
    from qsid_core.plant import is_nonlinear

    nonlinear = getattr(args, "a_text", None) is None and is_nonlinear(args.system)
    if not nonlinear and getattr(args, "lifting", None) is not None:
        raise UsageError(
            f"argument --lifting: only for a nonlinear --system (see 'qsid systems'); {args.system!r} is linear"
        )
    return nonlinear


def _typed(args: argparse.Namespace) -> set[str]:
    """The long options typed on the command line (``--steps 5`` and ``--steps=5`` alike)."""
    return {a.split("=", 1)[0] for a in getattr(args, "argv", ()) if a.startswith("--")}


#: The options a nonlinear run uses; any other typed option is refused rather than silently ignored.
SUPPORTED = frozenset(
    "--system --lifting --estimator --bits --realizations --trajectories --steps --seed --data-seed --dither-seed "
    "--range --limits --guard --no-guard --dither --horizon --mpc-steps --u-max --x0 --Q --R --no-mpc --json --out "
    "--quiet --target --cost-gap".split()
)


def _check_supported(args: argparse.Namespace) -> None:
    """A typed option the nonlinear sweep does not use is one line, never silently dropped."""
    bad = sorted(_typed(args) - SUPPORTED)
    if bad:
        raise UsageError(f"argument {bad[0]}: not available for a nonlinear plant yet")


def _pick(args: argparse.Namespace, flag: str, value: Any, nonlinear_default: Any) -> Any:
    """``value`` if ``flag`` was typed, else the nonlinear default."""
    return value if flag in _typed(args) else nonlinear_default


def koopman_config(args: argparse.Namespace) -> KoopmanConfig:
    """The nonlinear sweep's configuration from the command line."""
    from dataclasses import replace

    from qsid_core import parse_bits
    from qsid_core.plant import get_nonlinear
    from qsid_core.studies import KOOPMAN_MPC, KoopmanConfig

    from .runner import _quantizer

    _check_supported(args)
    base = KoopmanConfig()
    system = get_nonlinear(args.system)
    seed = getattr(args, "seed", None)
    mpc = None
    if not getattr(args, "no_mpc", False):
        mpc = replace(
            KOOPMAN_MPC,
            horizon=_pick(args, "--horizon", args.horizon, KOOPMAN_MPC.horizon),
            steps=_pick(args, "--mpc-steps", args.mpc_steps, KOOPMAN_MPC.steps),
            u_max=args.u_max,
            x0=getattr(args, "x0", None),
            Q=getattr(args, "q_diag", None),
            R=getattr(args, "r_diag", None),
        )
    return KoopmanConfig(
        system=system,
        lifting=args.lifting or base.lifting,
        estimator=args.estimator,
        bits=_pick(args, "--bits", tuple(parse_bits(args.bits)), base.bits),
        trajectories=_pick(args, "--trajectories", args.trajectories, base.trajectories),
        steps=_pick(args, "--steps", args.steps, base.steps),
        realizations=_pick(args, "--realizations", args.realizations, base.realizations),
        data_seed=next(v for v in (args.data_seed, seed, base.data_seed) if v is not None),
        dither_seed=next(v for v in (args.dither_seed, seed, base.dither_seed) if v is not None),
        quantizer=_quantizer(args, system),
        mpc=mpc,
    )


def _pm(s: dict[str, float]) -> str:
    return f"{g(s['mean'])} +/- {g(s['std'])}" if math.isfinite(s["mean"]) else "-"


def format_koopman(d: dict[str, Any]) -> str:
    """The readable table of a nonlinear sweep dict."""
    c = d["config"]
    lines = [
        f"{d['system']}: lifting {c['lifting']} ({c['features']} features), estimator {c['estimator']}, "
        f"{d['data']['runs_used']} runs x {c['steps']} steps, {c['realizations']} realizations, {c['dither']} dither"
        + (", guard band" if c["guard"] else ""),
        "b  err_G (vs unquantized EDMD)  large-data limit  err_A            err_B            prediction err   converged",
    ]
    for r in d["results"]:
        conv = (
            "-" if r["stabilized_fraction"] is None else f"{r['closed_loop_outcomes']['converged']}/{r['realizations']}"
        )
        lim = (r.get("large_data") or {}).get("err_G")
        lines.append(
            f"{r['bits']:<2} {_pm(r['err_G']):<28} {'-' if lim is None else g(lim):<17} "
            f"{_pm(r['err_A']):<16} {_pm(r['err_B']):<16} "
            f"{_pm(r['prediction_error']):<16} {conv}"
        )
    ref = d["reference"]
    lines.append(
        f"unquantized EDMD: prediction error {g(ref['prediction_error'])}"
        + (f", Koopman MPC {ref['closed_loop_outcome']}" if ref["closed_loop_outcome"] else "")
    )
    if d["data"]["left_box"]:
        lines.append(d["data"]["left_box"])
    for note in sorted({n for r in d["results"] for n in r["notes"]}):
        lines.append(f"note: {note}")
    limits = {r["large_data"]["note"] for r in d["results"] if r.get("large_data", {}).get("note")}
    for note in sorted(limits):
        lines.append(f"large-data limit: {note}")
    if "large_data_hypotheses" in d:
        lines.append("large-data limit assumes: " + "; ".join(d["large_data_hypotheses"]))
    lines.append(f"note: {d['certificates']}")
    return "\n".join(lines)


def _run(args: argparse.Namespace, rep: Reporter) -> dict[str, Any]:
    from qsid_core.studies import run_koopman_sweep

    cfg = koopman_config(args)
    cfg.dictionary()  # a bad --lifting is reported before anything runs
    rep.stage(
        f"nonlinear sweep of {cfg.plant().name}: {cfg.trajectories} x {cfg.steps}, lifting {cfg.lifting}, "
        f"{len(cfg.bits)} word lengths x {cfg.realizations} realizations"
    )
    return run_koopman_sweep(cfg).to_dict()


def run_sweep(args: argparse.Namespace, rep: Reporter) -> int:
    """``qsid sweep`` for a nonlinear plant."""
    out = out_file(args.out, rep, inputs=input_files(args))
    d = _run(args, rep)
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n")
    print(text if args.json else format_koopman(d))
    return 0


def run_bits(args: argparse.Namespace, rep: Reporter) -> int:
    """``qsid bits`` for a nonlinear plant: b_observed only (the linear certificates do not apply)."""
    if getattr(args, "no_mpc", False):
        raise UsageError("qsid bits needs the closed loops; drop --no-mpc")
    out = out_file(args.out, rep, inputs=input_files(args))
    d = _run(args, rep)
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
        write_text(out, text + "\n")
    if args.json:
        print(text)
        return 0
    print("b  converged")
    for r in rows:
        print(f"{r['bits']:<2} {r['closed_loop_outcomes']['converged']}/{r['realizations']}")
    got = f"b_observed = {b_obs}" if b_obs is not None else "no swept b reaches the target"
    print(f"{got} (at least {100 * args.target:g}% of the loops converge from there on); {d['certificates']}")
    return 0
