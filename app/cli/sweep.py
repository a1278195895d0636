"""``qsid sweep``: identification errors, Theorem 1, overload, MPC cost and ultimate bound over b; for a nonlinear
``--system`` (:func:`app.cli.study.wanted`) the lifted model's errors, its prediction error and the Koopman MPC's
outcomes over b (:func:`format_koopman`)."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from .figure_out import add_figure_arguments, check_figure, write_figure
from .files import input_files, out_file, save_output, write_text
from .output import dumps, format_table, g, sweep_dict, text_table
from .parser import add_run_options
from .runner import UsageError, system_from_args
from .runner import run as run_sweep
from .study import add_nonlinear_options, nonlinear_result, wanted

if TYPE_CHECKING:
    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "KOOPMAN_HEAD", "add_arguments", "format_koopman", "run"]

HELP = "sweep the word length b: identification errors, theory, MPC cost"
DESCRIPTION = (
    "Sweep the word length b: identification errors (mean +- std over dither realizations), Theorem 1 "
    "prediction, overload, MPC cost on the true system, ultimate bound."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    add_nonlinear_options(p)
    p.add_argument(
        "--config",
        metavar="FILE",
        default=None,
        help="take every setting from FILE: a previous JSON result (--out) or a TOML file with the "
        "same keys (system, bits, dither, ...); flags given with non-default values override it",
    )
    p.add_argument("--no-mpc", action="store_true", help="skip the MPC closed loops (identification and theory)")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout instead of a table")
    p.add_argument(
        "--csv",
        metavar="FILE",
        default=None,
        help="also write one row per (b, estimator, realization): errors, overload, MPC cost, failure "
        "kind, final norm (checked before the run like --out)",
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        default=None,
        help="also write the JSON to FILE (checked before the run; an existing FILE is replaced, "
        "with a note on stderr; never an input file)",
    )
    add_figure_arguments(p)


def run(args: argparse.Namespace, rep: Reporter) -> int:
    if wanted(args):
        return _run_nonlinear(args, rep)
    cfg = None
    inputs = input_files(args)
    if args.config is not None:
        import argparse
        from pathlib import Path

        from qsid_core import get_system

        from .study import config_from_file

        bare = argparse.ArgumentParser(add_help=False)
        add_arguments(bare)
        cfg = config_from_file(args, bare.parse_args([]), not args.no_mpc)
        system = get_system(cfg.system)
        inputs = inputs + [Path(args.config)]
    else:
        system = system_from_args(args)
    out = out_file(args.out, rep, inputs=inputs)
    csv_out = out_file(args.csv, rep, flag="--csv", inputs=inputs)
    if out is not None and csv_out is not None and out.resolve() == csv_out.resolve():
        raise UsageError("arguments --out and --csv name the same file; give two names")
    fig_out = check_figure(args, rep, inputs, (("--out", out), ("--csv", csv_out)))
    res, _ = run_sweep(args, system, not args.no_mpc, rep, cfg=cfg)
    d = sweep_dict(res)
    if csv_out is not None:
        from qsid_core import write_csv

        rows: list[int] = []
        csv_out = save_output(csv_out, lambda p: rows.append(write_csv(res, p)), rep, "--csv")
        rep.stage(f"{rows[-1]} rows (b x realizations) written to {csv_out}")
    text = dumps(d)
    if out is not None:
        out = write_text(out, text + "\n", rep)
    write_figure(res, fig_out, args.figure_view, rep)
    rep.stage(f"done in {d['timing_s']['total']:.2f} s" + (f"; JSON written to {out}" if out else ""))
    print(text if args.json else format_table(d))
    return 0


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


def _run_nonlinear(args: argparse.Namespace, rep: Reporter) -> int:
    """``qsid sweep`` for a nonlinear plant."""
    out = out_file(args.out, rep, inputs=input_files(args))
    d = nonlinear_result(args, rep)
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n", rep)
    print(text if args.json else format_koopman(d))
    return 0
