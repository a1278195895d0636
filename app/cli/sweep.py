"""``qsid sweep``: identification errors, Theorem 1, overload, MPC cost and ultimate bound over b."""

from __future__ import annotations

from pathlib import Path

from .output import dumps, format_table
from .parser import add_run_options
from .runner import UsageError, check_writable, resolve_system, run as run_sweep, write_text

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run"]

HELP = "sweep the word length b: identification errors, theory, MPC cost"
DESCRIPTION = ("Sweep the word length b: identification errors (mean +- std over dither realizations), Theorem 1 "
               "prediction, overload, MPC cost on the true system, ultimate bound.")


def add_arguments(p) -> None:
    add_run_options(p)
    p.add_argument("--no-mpc", action="store_true", help="skip the MPC closed loops (identification and theory)")
    p.add_argument("--json", action="store_true", help="print one JSON object to stdout instead of a table")
    p.add_argument("--out", metavar="FILE", default=None, help="also write the JSON to FILE")


def run(args, rep) -> int:
    system = resolve_system(args.system)
    out = Path(args.out) if args.out else None
    if out is not None and out.is_dir():
        raise UsageError(f"argument --out: {args.out!r} is a directory; give a file name")
    if out is not None:  # fail before the run, not after it
        out.parent.mkdir(parents=True, exist_ok=True)
        check_writable(out.parent)
    res, _ = run_sweep(args, system, not args.no_mpc, rep)
    d = res.to_dict()
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n")
    rep.stage(f"done in {d['timing_s']['total']:.2f} s" + (f"; JSON written to {out}" if out else ""))
    print(text if args.json else format_table(d))
    return 0
