"""``qsid identify --data FILE``: your own recorded data, quantized at each b, identified by LS and BCLS.

The errors are against the LS estimate from the unquantized data (or ``--system``'s A and B);
the numbers are :func:`qsid_core.studies.recorded.identify_recorded`'s.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from app.settings.cli import add_option

from .files import out_file, write_text
from .output import dumps
from .parser import add_quantizer_options, engine
from .runner import UsageError, quantizer_from_args, resolve_system

if TYPE_CHECKING:
    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run", "REALIZATIONS"]

#: Dither realizations per word length of recorded data (fewer than a sweep's: a user's data can be large).
REALIZATIONS = 5

HELP = "identify your own recorded data (.npz or .csv) at each word length by LS and BCLS"
DESCRIPTION = (
    "Quantize recorded data (a .npz with x: runs x (steps+1) x n and u: runs x steps x m, or a .csv "
    "with columns run, t, x1..xn, u1..um) at each word length, identify A and B by LS and BCLS, and "
    "report their relative errors against the LS model of the unquantized data (or --system's), with "
    "Theorem 1's predicted LS errors from the data's own Psi Psi^T / T where its hypotheses hold."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    q0 = engine().quant
    g = p.add_argument_group("data")
    g.add_argument("--data", required=True, metavar="FILE", help="the recorded data, .npz or .csv")
    g.add_argument(
        "--system",
        default=None,
        metavar="NAME|FILE",
        help="a true model to compare with (default: LS on the unquantized data)",
    )
    g.add_argument("--bits", default="2:12", metavar="SPEC", help="word lengths (default: 2:12)")
    add_option(g, "realizations", default=REALIZATIONS)
    add_option(g, "dither_seed", default=engine().sweep.dither_seed)
    q = p.add_argument_group("quantizer")
    add_quantizer_options(q, q0, "quantizer range")
    r = p.add_argument_group("output")
    r.add_argument("--json", action="store_true", help="print one JSON object to stdout")
    r.add_argument("--out", metavar="FILE", default=None, help="also write the JSON to FILE")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def _pm(s: dict) -> str:
    return "-" if s["mean"] != s["mean"] else f"{s['mean']:.3e} +/- {s['std']:.1e}"


def _theory(r: dict, blk: str) -> str:
    t = r.get("theorem1")
    return "-" if not t or not t[f"holds_{blk}"] else f"{t[f'err_{blk}']:.3e}"


def format_table(d: dict) -> str:
    """The readable table of :meth:`RecordedResult.to_dict`: errors per b, Theorem 1's where it applies, notes."""
    head = ["b", "eps min..max", "LS err_A", "Thm1 A", "BCLS err_A", "LS err_B", "Thm1 B", "BCLS err_B", "overload"]
    rows = [
        [
            str(r["bits"]),
            f"{min(r['eps']):.2e}..{max(r['eps']):.2e}",
            _pm(r["ls"]["err_A"]),
            _theory(r, "A"),
            _pm(r["bcls"]["err_A"]),
            _pm(r["ls"]["err_B"]),
            _theory(r, "B"),
            _pm(r["bcls"]["err_B"]),
            f"{100 * r['overload_fraction']:.2f}%",
        ]
        for r in d["results"]
    ]
    w = [max(len(x) for x in col) for col in zip(head, *rows)]
    fmt = lambda cells: "  ".join(c.rjust(k) for c, k in zip(cells, w))  # noqa: E731
    lines = [
        f"recorded data: {d['runs']} runs x {d['steps']} steps; errors against {d['reference']}; Theorem 1 "
        "from the data's own Psi Psi^T / T (shown where its hypotheses hold)",
        fmt(head),
        fmt(["-" * k for k in w]),
        *map(fmt, rows),
    ]
    lines += [
        f"Theorem 1 at b = {r['bits']}: {'; '.join(r['theorem1']['why'])}"
        for r in d["results"]
        if r.get("theorem1") and r["theorem1"]["why"]
    ]
    lines += [f"note: {n}" for n in d["notes"]]
    return "\n".join(lines)


def run(args: argparse.Namespace, rep: Reporter) -> int:
    from qsid_core import identify_recorded, load_recorded

    rep.enabled = not args.quiet
    out = out_file(args.out, rep, inputs=[args.data])
    data = load_recorded(args.data)
    system = resolve_system(args.system) if args.system is not None else None
    if args.range_mode == "fixed" and args.limits is None:
        raise UsageError("argument --range fixed needs --limits LO,HI")
    spec = quantizer_from_args(args, _Shape(data.n, data.m))
    rep.stage(f"{args.data}: {data.trajectories} runs x {data.steps} steps, {data.n} states, {data.m} inputs")
    res = identify_recorded(data, args.bits, spec, args.realizations, args.dither_seed, system)
    d = res.to_dict()
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n", rep)
    print(text if args.json else format_table(d))
    return 0


class _Shape:
    """What :func:`app.cli.runner.quantizer_from_args` reads of a system: its name and channel counts."""

    def __init__(self, n: int, m: int):
        self.name, self.n, self.m = "recorded data", n, m
