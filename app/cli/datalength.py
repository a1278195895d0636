"""``qsid datalength``: LS and BCLS model errors against data length at one word length.

Finite data give an O(eps) error that falls with T; large data meet Theorem 1's
O(eps^2) bias floor (LS), which BCLS removes where its hypotheses hold. The
numbers are :func:`qsid_core.studies.datalength.run_datalength`'s; this module parses,
reports progress on stderr, and prints a table (or JSON) on stdout.
"""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from app.settings.cli import add_seed_option, add_setting_options, given_seeds, study_values
from app.settings.schema import DATA_GROUP, WHATIF_GROUP

from .files import input_files, out_file, write_text
from .output import dumps, g
from .parser import add_quantizer_options, add_running_options, pos_int
from .runner import check_channels, executor, quantizer_from_args, resolve_system

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run"]

#: The what-if fields a study's record holds when set (:meth:`qsid_core.DataLengthConfig.what_ifs`).
WHAT_IFS = ("state_amplitude", "noise", "noise_known", "input_bits", "state_bits")

HELP = "model error against data length at one word length (LS, BCLS, Theorem 1's floor)"
DESCRIPTION = (
    "Relative errors of A and B (mean +- std over dither realizations) of LS and BCLS against the "
    "number of regression samples T at one word length, with Theorem 1's large-data prediction. "
    "Trajectories x steps per length are chosen by the engine and reported."
)


def _samples(text: str) -> tuple[int, ...]:
    """``1000,10000,1e5``: whole sample counts (their range is the engine's to check)."""
    out = []
    for part in text.split(","):
        try:
            v = float(part)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be comma-separated sample counts like 1000,10000; got {text!r}"
            ) from None
        if not (math.isfinite(v) and v.is_integer() and abs(v) < 1e15):
            raise argparse.ArgumentTypeError(f"sample counts must be whole numbers; got {part.strip()!r}")
        out.append(int(v))
    return tuple(out)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The study's options: those of the settings with a ``datalength`` path in the settings table (defaults
    ``DataLengthConfig()``'s), and the system, word length and data lengths written here."""
    from qsid_core import DataLengthConfig
    from qsid_core.studies import DEFAULT_SAMPLES

    d = DataLengthConfig()
    g_ = p.add_argument_group(DATA_GROUP)
    g_.add_argument(
        "--system",
        default=d.system,
        metavar="NAME|FILE",
        help=f"preset name or a .toml/.json system file (default: {d.system})",
    )
    g_.add_argument("--bits", type=pos_int, default=d.bits, metavar="B", help=f"word length (default: {d.bits})")
    g_.add_argument(
        "--samples",
        type=_samples,
        default=DEFAULT_SAMPLES,
        metavar="T1,T2,..",
        help="total regression samples per length, e.g. 1000,10000,100000 (default: "
        f"{len(DEFAULT_SAMPLES)} lengths from {DEFAULT_SAMPLES[0]} to {DEFAULT_SAMPLES[-1]})",
    )
    add_setting_options(g_, DATA_GROUP, d, {"realizations": "dither realizations per length"}, study="datalength")
    add_seed_option(g_)
    q = p.add_argument_group("quantizer")
    add_quantizer_options(q, d.quantizer, "range of the largest data set, used at every length")
    add_setting_options(p.add_argument_group(WHATIF_GROUP), WHATIF_GROUP, d, study="datalength")
    r = p.add_argument_group("output and running")
    r.add_argument("--json", action="store_true", help="print one JSON object (one row per length) to stdout")
    r.add_argument("--out", metavar="FILE", default=None, help="also write the JSON to FILE")
    add_running_options(p)


def _pm(s: dict) -> str:
    return "-" if s.get("mean") is None else f"{s['mean']:.3e} +/- {s['std']:.1e}"


def _what_ifs(c: dict) -> str:
    """``"; state amplitude 2, noise 0.01"``: the what-ifs a study's config holds (none: "")."""
    words = [f"{k.replace('_', ' ')} {','.join(map(str, v)) if isinstance(v, list) else v}" for k, v in c.items()]
    shown = [w for k, w in zip(c, words) if k in WHAT_IFS]
    return f"; {', '.join(shown)}" if shown else ""


def format_table(d: dict) -> str:
    """The readable table of :meth:`DataLengthResult.to_dict`."""
    c = d["config"]
    head = ["T", "runs x steps", "LS err_A", "LS err_B", "BCLS err_A", "BCLS err_B", "Thm1 A", "Thm1 B", "overload"]
    rows = [
        [
            str(r["samples"]),
            f"{r['trajectories']} x {r['steps']}",
            _pm(r["ls"]["err_A"]),
            _pm(r["ls"]["err_B"]),
            _pm(r["bcls"]["err_A"]),
            _pm(r["bcls"]["err_B"]),
            g(r["err_A_theory"], ".3e"),
            g(r["err_B_theory"], ".3e"),
            f"{100 * r['overload_fraction']:.2f}%",
        ]
        for r in d["rows"]
    ]
    widths = [max(len(h), *(len(row[i]) for row in rows)) if rows else len(h) for i, h in enumerate(head)]

    def fmt(cells: Sequence[str]) -> str:
        return "  ".join(cell.rjust(w) for cell, w in zip(cells, widths))

    eps = d["eps"]
    lines = [
        f"system {d['system']}, b = {d['bits']}: {c['realizations']} realizations, range {c['range']}"
        f"{' + guard' if c['guard'] else ', no guard'}, dither {c['dither']}, inputs "
        f"U[-{c['input_amplitude']:g}, {c['input_amplitude']:g}], eps {min(eps):.2e}..{max(eps):.2e} "
        f"(the same at every length){_what_ifs(c)}",
        fmt(head),
        fmt(["-" * w for w in widths]),
        *(fmt(r) for r in rows),
        "errors are relative (Frobenius), mean +/- std over realizations; Thm1 = Theorem 1's large-data "
        "prediction (LS's floor); runs x steps chosen by the engine (nested prefixes of one data set)",
    ]
    fb = sum(r["bcls_fallbacks"] for r in d["rows"])
    if fb:
        lines.append(f"BCLS fell back to LS in {fb} realization(s) (corrected Gram matrix not positive definite)")
    return "\n".join(lines)


def run(args: argparse.Namespace, rep: Reporter) -> int:
    from qsid_core import DataLengthConfig, run_datalength
    from qsid_core.studies import runs_and_steps

    system = resolve_system(args.system)
    out = out_file(args.out, rep, inputs=input_files(args))
    cfg = DataLengthConfig(
        system=system,
        bits=args.bits,
        samples=args.samples,
        quantizer=quantizer_from_args(args, system),
        # the settings table's (realizations, amplitudes, what-ifs, seeds); each seed typed, else --seed's
        **{**study_values(args, "datalength"), **given_seeds(args)},
    )
    check_channels(cfg, system)
    plan = ", ".join(
        f"{T}: {'x'.join(map(str, runs_and_steps(T, cfg.steps_per_run, cfg.min_runs)))}" for T in cfg.samples
    )
    rep.stage(
        f"system {system.name!r}, b = {cfg.bits}, {cfg.realizations} realizations; runs x steps per length: {plan}"
    )
    with executor(args, rep) as (pool, nw):
        res = run_datalength(cfg, pool, progress=rep, tasks=max(4, 2 * nw))
    d = res.to_dict()
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n", rep)
    rep.stage("done" + (f"; JSON written to {out}" if out else ""))
    print(text if args.json else format_table(d))
    return 0
