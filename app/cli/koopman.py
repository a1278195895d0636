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

from app.settings.cli import add_setting_options, given_seeds
from app.settings.schema import NONLINEAR_GROUP, SETTINGS, nonlinear_settings

from .files import input_files, out_file, write_text
from .output import dumps, g, text_table
from .runner import UsageError

if TYPE_CHECKING:
    from qsid_core.studies import KoopmanConfig

    from .runner import Reporter

__all__ = ["SUPPORTED", "add_nonlinear_options", "format_koopman", "koopman_config", "run_bits", "run_sweep", "wanted"]


def add_nonlinear_options(p: argparse.ArgumentParser) -> None:
    """The options of the settings table's nonlinear group (``--lifting``, ``--sane-box``, ``--converged-radius``)."""
    add_setting_options(p.add_argument_group(NONLINEAR_GROUP), NONLINEAR_GROUP)


#: The flags only a nonlinear plant uses (the settings table's nonlinear group).
NONLINEAR_ONLY = frozenset(f for s in SETTINGS if s.cli_group == NONLINEAR_GROUP for f in s.flags)


def wanted(args: argparse.Namespace) -> bool:
    """Whether the run is a nonlinear one (a nonlinear ``--system``); a nonlinear plant's own option typed for a
    linear plant is an error."""
    from qsid_core.plant import is_nonlinear

    nonlinear = getattr(args, "a_text", None) is None and is_nonlinear(args.system)
    bad = sorted(_typed(args) & NONLINEAR_ONLY)
    if not nonlinear and bad:
        system = "the typed system" if getattr(args, "a_text", None) is not None else repr(args.system)
        raise UsageError(f"argument {bad[0]}: only for a nonlinear --system (see 'qsid systems'); {system} is linear")
    return nonlinear


def _typed(args: argparse.Namespace) -> set[str]:
    """The long options typed on the command line (``--steps 5`` and ``--steps=5`` alike)."""
    return {a.split("=", 1)[0] for a in getattr(args, "argv", ()) if a.startswith("--")}


#: The options a nonlinear run uses: the flags of the settings it honours (those with a ``nonlinear`` path in
#: the settings table) and the run's own; any other typed option is refused rather than silently ignored.
SUPPORTED = frozenset(f for s in nonlinear_settings() for f in s.flags) | frozenset(
    "--bits --seed --no-mpc --json --out --quiet --target --total-bits".split()
)


def _check_supported(args: argparse.Namespace) -> None:
    """A typed option the nonlinear sweep does not use is one line, never silently dropped."""
    bad = sorted(_typed(args) - SUPPORTED)
    if bad:
        raise UsageError(f"argument {bad[0]}: not available for a nonlinear plant yet")


#: The parsed names of hand-made flags whose dest is not their setting's name.
_DEST = {"--Q": "q_diag", "--R": "r_diag"}


def _given(args: argparse.Namespace, typed: set[str]) -> dict[str, Any]:
    """The values of the typed options of the settings a nonlinear run honours, by their ``nonlinear`` path
    (``"trajectories"``, ``"mpc.horizon"``, ``"box"``); ``--seed`` gives both seeds unless they are typed. The
    system, the word lengths and the quantizer's options are read apart (:func:`koopman_config`)."""
    out: dict[str, Any] = {}
    for s in nonlinear_settings():
        path = s.nonlinear
        if path is None or path in ("system", "bits") or path.startswith("quantizer.") or not typed & set(s.flags):
            continue
        out[path] = getattr(args, s.dest if s.flag else _DEST.get(s.flags[0], s.name))
    for name, value in given_seeds(args).items():  # typed, else --seed's
        out.setdefault(name, value)
    return out


def koopman_config(args: argparse.Namespace) -> KoopmanConfig:
    """The nonlinear sweep's configuration from the command line: ``KoopmanConfig()``'s defaults (the nonlinear
    ones: 2000 x 100 runs, 20 realizations, b = 2..8, :data:`~qsid_core.studies.KOOPMAN_MPC`) where an option is
    not typed."""
    from dataclasses import replace

    from qsid_core import parse_bits
    from qsid_core.plant import get_nonlinear
    from qsid_core.studies import KOOPMAN_MPC, KoopmanConfig

    from .runner import quantizer_from_args

    _check_supported(args)
    typed = _typed(args)
    given = _given(args, typed)
    system = get_nonlinear(args.system)  # an unknown name or a bad plant file: one line before anything runs
    mpc = None
    if not getattr(args, "no_mpc", False):
        mpc = replace(KOOPMAN_MPC, **{k.removeprefix("mpc."): v for k, v in given.items() if k.startswith("mpc.")})
    kw = {k: v for k, v in given.items() if "." not in k}
    if "--bits" in typed:
        kw["bits"] = tuple(parse_bits(args.bits))
    return KoopmanConfig(
        system=args.system if isinstance(args.system, str) else system,
        quantizer=quantizer_from_args(args, system),
        mpc=mpc,
        **kw,
    )


def _pm(s: dict[str, float]) -> str:
    return f"{g(s['mean'])} +/- {g(s['std'])}" if math.isfinite(s["mean"]) else "-"


def _limit(r: dict[str, Any]) -> str:
    """The large-data limit's cell: its err_G, "0 (= EDMD)" where the limit is the unquantized EDMD itself (the
    de-biased estimate), "n/a" where no limit applies (no exact formula: the note under the table says why)."""
    lim = (r.get("large_data") or {}).get("err_G")
    if lim is None:
        return "n/a"
    return "0 (= EDMD)" if lim == 0 else g(lim)


#: The nonlinear sweep table's columns.
KOOPMAN_HEAD = (
    "b",
    "err_G (vs unquantized EDMD)",
    "large-data limit",
    "err_A",
    "err_B",
    "prediction err",
    "converged",
    "within radius",
    "settled offset med/max",
)


def _within(r: dict[str, Any]) -> str:
    return "-" if r.get("within_radius") is None else f"{r['within_radius']}/{r['realizations']}"


def _offset(s: dict[str, float] | None) -> str:
    return "-" if not s else f"{g(s['median'])}/{g(s['max'])}"


def format_koopman(d: dict[str, Any]) -> str:
    """The readable table of a nonlinear sweep dict (columns aligned as the linear sweep's)."""
    c = d["config"]
    rows = [
        [
            str(r["bits"]),
            _pm(r["err_G"]),
            _limit(r),
            _pm(r["err_A"]),
            _pm(r["err_B"]),
            _pm(r["prediction_error"]),
            "-"
            if r["stabilized_fraction"] is None
            else f"{r['closed_loop_outcomes']['converged']}/{r['realizations']}",
            _within(r),
            _offset(r.get("settled_offset")),
        ]
        for r in d["results"]
    ]
    lines = [
        f"{d['system']}: lifting {c['lifting']} ({c['features']} features), estimator {c['estimator']}, "
        f"{d['data']['runs_used']} runs x {c['steps']} steps, {c['realizations']} realizations, {c['dither']} dither"
        + (", guard band" if c["guard"] else ""),
        *text_table(KOOPMAN_HEAD, rows),
    ]
    ref = d["reference"]
    lines.append(
        f"unquantized EDMD: prediction error {g(ref['prediction_error'])}"
        + (f", Koopman MPC {ref['closed_loop_outcome']}" if ref["closed_loop_outcome"] else "")
        + (
            f", settled offset {g(ref['settled_offset'])} (what the dictionary alone leaves)"
            if ref.get("settled_offset") is not None
            else ""
        )
    )
    lines.append(
        "a loop converged when it settles (mean |x| over its last 10 % of steps) within 1e-6 |x0| of the origin, "
        f"else it is bounded at that offset; within radius: |x_end| <= {g(c['convergence_radius'])}"
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
    from qsid_core.studies import Study

    cfg = koopman_config(args)
    cfg.dictionary()  # a bad --lifting is reported before anything runs
    rep.stage(
        f"nonlinear sweep of {cfg.plant().name}: {cfg.trajectories} x {cfg.steps}, lifting {cfg.lifting}, "
        f"{len(cfg.bits)} word lengths x {cfg.realizations} realizations"
    )
    return Study(cfg).run().to_dict()


def run_sweep(args: argparse.Namespace, rep: Reporter) -> int:
    """``qsid sweep`` for a nonlinear plant."""
    out = out_file(args.out, rep, inputs=input_files(args))
    d = _run(args, rep)
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n", rep)
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
