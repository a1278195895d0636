"""``qsid budget``: a fixed budget of bits, spent on fewer, finer samples or more, coarser ones.

At each word length b the budget buys ``floor(T / (steps (n + m) b))`` runs; the numbers are
:func:`qsid_core.studies.run_budget`'s (linear and nonlinear plants); this module parses, reports progress on
stderr and prints a table (or JSON) on stdout.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from app.settings.cli import add_option

from .files import input_files, out_file, write_text
from .output import dumps, g
from .parser import add_run_options
from .runner import UsageError, executor
from .study import add_nonlinear_options, engine_config

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .runner import Reporter

__all__ = ["HELP", "DESCRIPTION", "add_arguments", "run", "format_allocation", "format_budget"]

HELP = "a fixed budget of bits: runs bought, model error and loops per word length, the knee"
DESCRIPTION = (
    "A sensor link carries --total-bits T. Every sample of every state and input channel is sent at b bits, "
    "so word length b buys floor(T / (steps (n + m) b)) runs of --steps samples. For each b: the runs bought, "
    "the model error err_G (mean +- std over --realizations, each with its own data, sensor noise and "
    "dither), Theorem 1's LS limit and the predicted error (linear plants), and unless --no-mpc the share "
    "of MPC loops that converge on the true plant and their cost gap. Then b_best (least mean error), "
    "b_knee (the smallest b within 25 % of it) and b_loop (the smallest b whose loops meet the target of "
    "'qsid bits': at least 95 % stabilized, cost within 1 %). With --bits-per-sample B: a split of B bits per "
    "sample between the channels, proposed from the predicted error, against the uniform split (model errors)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    add_nonlinear_options(p)
    a = p.add_argument_group("bit budget")
    add_option(a, "total_bits")
    add_option(a, "bits_per_sample")
    for act in p._actions:
        if act.dest == "total_bits":
            act.required = True
        if act.dest == "trajectories":
            act.help = "not used: the budget sets the runs of every b"
    a.add_argument("--no-mpc", action="store_true", help="skip the MPC closed loops (model errors only)")
    a.add_argument("--json", action="store_true", help="print one JSON object to stdout instead of a table")
    a.add_argument(
        "--out",
        metavar="FILE",
        default=None,
        help="also write the JSON to FILE (checked before the run; an existing FILE is replaced)",
    )


def _typed(args: argparse.Namespace) -> set[str]:
    return {a.split("=", 1)[0] for a in getattr(args, "argv", ()) if a.startswith("--")}


def _study(args: argparse.Namespace) -> Any:
    """The sweep's configuration the budget study runs (its ``trajectories`` unused)."""
    if "--trajectories" in _typed(args):
        raise UsageError("argument --trajectories: the budget sets the runs of every b; drop it")
    return engine_config(args, not args.no_mpc)


def _pm(s: dict[str, Any]) -> str:
    return "-" if s.get("mean") is None else f"{s['mean']:.2e} +/- {s['std']:.1e}"


def _loops(r: dict[str, Any]) -> list[str]:
    oc = r.get("closed_loop_outcomes")
    share = r.get("stabilized_fraction")
    gap = r.get("cost_gap")
    off = r.get("settled_offset")
    return [
        "-" if share is None else f"{100 * share:.1f}%",
        "-" if gap is None else f"{100 * gap + 0.0:+.1f}%".replace("-0.0%", "+0.0%"),
        "-" if not oc else "/".join(str(oc[k]) for k in ("converged", "bounded", "diverged", "failed")),
        "-" if not off else f"{g(off['median'], '.3g')}/{g(off['max'], '.3g')}",
    ]


def format_budget(d: dict[str, Any]) -> str:
    """The plain table of a ``qsid budget`` JSON dict, then the named word lengths."""
    c = d["config"]
    linear = not d["nonlinear"]
    loops = c["mpc"]
    head = ["b", "runs", "samples", "err_G mean +/- std"]
    head += ["predicted", "Thm 1 (LS limit)"] if linear else []
    head += ["stabilized", "cost gap"] if linear else ["stabilized"]
    head += ["conv/bound/div/fail"] + ([] if linear else ["within radius", "settled offset med/max"])
    head = head if loops else head[: 6 if linear else 4]
    rows = []
    for r in d["rows"]:
        if not r["identifiable"]:
            rows.append([str(r["bits"]), str(r["trajectories"]), str(r["samples"]), "not identifiable"])
            rows[-1] += [""] * (len(head) - 4)
            continue
        cells = [str(r["bits"]), str(r["trajectories"]), str(r["samples"]), _pm(r["err_G"])]
        if linear:
            cells += [g(r.get("predicted_err_G"), ".2e"), g(r.get("theorem1_err_G"), ".2e")]
        if loops:
            share, gap, oc, off = _loops(r)
            within = (
                "-"
                if r.get("within_radius") is None
                else f"{r['within_radius']}/{sum(r['closed_loop_outcomes'].values())}"
            )
            cells += [share, gap, oc] if linear else [share, oc, within, off]
        rows.append(cells)
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]

    def fmt(cells: Sequence[str]) -> str:
        return "  ".join(x.rjust(w) for x, w in zip(cells, widths))

    noise = c.get("noise") or [0.0]
    lines = [
        f"system {d['system']}: a budget of {c['total_bits']:g} bits, runs of {c['steps']} steps, "
        f"{c['realizations']} realizations (each its own data, noise and dither), estimator {c['estimator']}, "
        f"dither {c['dither']}"
        + (f", lifting {c['lifting']}" if "lifting" in c else "")
        + (f", sensor noise {','.join(f'{v:g}' for v in noise)}" if any(noise) else "")
        + (" (known to BCLS)" if c.get("noise_known") and any(noise) else ""),
        fmt(head),
        fmt(["-" * w for w in widths]),
        *(fmt(r) for r in rows),
        *(f"b = {r['bits']}: {r['note']}" for r in d["rows"] if r.get("note")),
    ]
    lines.append(_named(d))
    return "\n".join(lines)


def _b(v: int | None) -> str:
    return "none" if v is None else str(v)


def _named(d: dict[str, Any]) -> str:
    knee = math.floor(100 * d["config"]["knee"] + 0.5)
    text = (
        f"b_best = {_b(d['b_best'])} (least mean error), b_knee = {_b(d['b_knee'])} (the smallest b within "
        f"{knee} % of it)"
    )
    if not d["nonlinear"]:
        text += f", predicted b_knee = {_b(d['b_knee_predicted'])}"
    if d["config"]["mpc"]:
        c = d["config"]
        target = f"at least {100 * c['target']:g} % of the loops stabilized" + (
            f" with a cost within {100 * c['cost_gap']:g} %" if not d["nonlinear"] else ""
        )
        text += f"; b_loop = {_b(d['b_loop'])} (the smallest b with {target})"
    return text


def format_allocation(d: dict[str, Any]) -> str:
    """The plain table of a ``qsid budget --bits-per-sample`` JSON dict: the two splits and their errors."""
    c = d["config"]
    head = ["split", *d["channels"], "predicted", "err_G mean +/- std"]
    rows = [
        [name, *map(str, d[name]["bits"]), g(d[name]["predicted_err_G"], ".2e"), _pm(d[name]["err_G"])]
        for name in ("uniform", "proposed")
    ]
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]

    def fmt(cells: Sequence[str]) -> str:
        return "  ".join(x.rjust(w) for x, w in zip(cells, widths))

    noise = c.get("noise") or [0.0]
    r = d["ratio"]
    return "\n".join(
        [
            f"system {d['system']}: a budget of {c['total_bits']:g} bits at {c['bits_per_sample']} bits per sample "
            f"buys {d['trajectories']} runs of {c['steps']} steps; {c['realizations']} realizations (each its own "
            f"data, noise and dither, both splits on the same), estimator {c['estimator']}"
            + (f", sensor noise {','.join(f'{v:g}' for v in noise)}" if any(noise) else "")
            + (" (known to BCLS)" if c.get("noise_known") and any(noise) else ""),
            fmt(head),
            fmt(["-" * w for w in widths]),
            *(fmt(row) for row in rows),
            f"proposed / uniform error per realization: mean {g(r['mean'], '.3g')}, median {g(r['median'], '.3g')}; "
            f"the proposal lower in {d['proposed_better']} of {c['realizations']}",
        ]
    )


def _emit(args: argparse.Namespace, rep: Reporter, out: Any, d: dict, table: Callable[[dict], str]) -> int:
    """Write the result ``d`` to ``out`` (if any) as JSON, and print it as JSON or as ``table(d)``."""
    text = dumps(d)
    if out is not None:
        write_text(out, text + "\n")
        rep.stage(f"JSON written to {out}")
    rep.stage(f"done in {d['timing_s']['total']:.2f} s")
    print(text if args.json else table(d))
    return 0


def _run_allocation(args: argparse.Namespace, rep: Reporter, cfg: Any, out: Any) -> int:
    from qsid_core.studies import run_allocation

    if {"--bits", "--no-mpc"} & _typed(args):
        raise UsageError("argument --bits-per-sample: the split is of B bits per sample, with no b swept and no loops; "
                         "drop --bits and --no-mpc")  # fmt: skip
    rep.stage(f"allocation of {cfg.bits_per_sample} bits per sample; {cfg.study.realizations} realizations")
    with executor(args, rep) as (pool, _nw):
        res = run_allocation(cfg, pool, progress=rep)
    return _emit(args, rep, out, res.to_dict(), format_allocation)


def run(args: argparse.Namespace, rep: Reporter) -> int:
    from qsid_core.studies import BudgetConfig, run_budget

    study = _study(args)
    out = out_file(args.out, rep, inputs=input_files(args))
    cfg = BudgetConfig(args.total_bits, study, bits_per_sample=args.bits_per_sample)
    if cfg.bits_per_sample is not None:
        return _run_allocation(args, rep, cfg, out)
    plan, skipped = cfg.plan()  # a budget that identifies nothing: one line before any work
    rep.stage(
        f"budget of {args.total_bits:g} bits: "
        + ", ".join(f"b = {b}: {k} runs" for b, k in plan)
        + (f" (not identifiable at b = {', '.join(map(str, skipped))})" if skipped else "")
        + f"; {study.realizations} realizations"
    )
    with executor(args, rep) as (pool, _nw):
        res = run_budget(cfg, pool, progress=rep)
    return _emit(args, rep, out, res.to_dict(), format_budget)
