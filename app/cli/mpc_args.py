"""The MPC options of ``qsid sweep``/``bits``/``reproduce`` turned into the engine's :class:`~qsid_core.MPCConfig`."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from .parser import UsageError

if TYPE_CHECKING:
    from qsid_core import LTISystem, MPCConfig

__all__ = ["mpc_config"]


def _reference(text: str | None, system: LTISystem) -> str | tuple[tuple[float, ...], ...] | None:
    """``--reference``: a text form (checked against the system's states) or the samples of a CSV file."""
    if text is None:
        return None
    from qsid_core.control import KINDS, parse_reference

    if text.split(":", 1)[0].strip().lower() in KINDS:
        parse_reference(text, system.state_names)  # one clear error now, before any work
        return text
    p = Path(text)
    if not p.is_file():
        raise UsageError(f"argument --reference: {text!r} is neither step:/sine:/square:... nor a CSV file")
    import numpy as np

    try:
        rows = [ln for ln in p.read_text(encoding="utf-8").splitlines() if ln.strip()]
        if rows and any(c.isalpha() for c in rows[0].replace("e", "").replace("E", "")):
            rows = rows[1:]  # a header row
        data = np.array([[float(v) for v in ln.split(",")] for ln in rows], dtype=float)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise UsageError(
            f"argument --reference: cannot read {text!r} as CSV numbers ({' '.join(str(exc).split())})"
        ) from None
    if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != system.n:
        raise UsageError(
            f"argument --reference: {text!r} needs one row per step and {system.n} columns (one per "
            f"state: {', '.join(system.state_names)})"
        )
    return tuple(tuple(r) for r in data.tolist())


def mpc_config(args: argparse.Namespace, system: LTISystem) -> MPCConfig:
    """The engine's :class:`~qsid_core.MPCConfig` for parsed arguments (shapes checked before any work)."""
    from app.settings.schema import engine_field, plain
    from qsid_core import MPCConfig

    if len(args.u_max) not in (1, system.m):
        raise UsageError(
            f"argument --u-max: give 1 or {system.m} values for system {system.name!r}; got {len(args.u_max)}"
        )
    u_max = args.u_max[0] if len(args.u_max) == 1 else args.u_max
    qf = getattr(args, "qf", None)
    if qf == "Q":  # the stage weight as the terminal weight
        Q = system.Q
        assert Q is not None  # LTISystem fills Q in __post_init__
        if args.q_diag is None and abs(Q).sum() != abs(Q.diagonal()).sum():
            raise UsageError(f"argument --Qf: Q of system {system.name!r} is not diagonal; give Qf as numbers")
        qf = args.q_diag if args.q_diag is not None else tuple(float(x) for x in Q.diagonal())
    reference = _reference(getattr(args, "reference", None), system)
    if reference is not None and args.x_ref is not None:
        raise UsageError("arguments --reference and --x-ref exclude each other (a reference is constant or not)")
    mcfg = MPCConfig(
        # the options of the settings table whose value is the engine's (horizon, steps, loop seed, ...)
        **{engine_field(s): getattr(args, s.dest) for s in plain("mpc", cli=True) if hasattr(args, s.dest)},
        u_max=u_max,
        x0=args.x0,
        x_ref=args.x_ref,
        reference=reference,
        tracking=getattr(args, "tracking", "letter"),
        x_max=args.x_max,
        xf_max=getattr(args, "xf_max", None),
        Qf=qf,
        Q=args.q_diag,
        R=args.r_diag,
        disturbance=getattr(args, "disturbance", (0.0, "gaussian"))[0],
        disturbance_kind=getattr(args, "disturbance", (0.0, "gaussian"))[1],
        feedback_bits=getattr(args, "feedback_bits", None),
    )
    mcfg.resolve(system)  # shape checks now, before any work
    return mcfg
