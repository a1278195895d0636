"""``qsid sweep``: identification errors, Theorem 1, overload, MPC cost and ultimate bound over b."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from . import koopman
from .figure_out import add_figure_arguments, check_figure, write_figure
from .files import input_files, out_file, save_output, write_text
from .koopman import add_nonlinear_options
from .output import dumps, format_table, sweep_dict
from .parser import add_run_options
from .runner import UsageError, system_from_args
from .runner import run as run_sweep

if TYPE_CHECKING:
    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run"]

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
    if koopman.wanted(args):
        return koopman.run_sweep(args, rep)
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
