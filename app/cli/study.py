"""``qsid sweep --config FILE``: a saved study (a JSON result or a TOML file) as a SweepConfig."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.settings.cli import given_seeds
from app.settings.schema import SETTINGS

from .runner import UsageError, check_channels, one_line

if TYPE_CHECKING:
    from qsid_core import SweepConfig

__all__ = ["config_from_file"]


#: flags whose non-default value overrides a --config file, and the SweepConfig field each sets (the settings
#: table's flags, and the hand-made ones whose value is one field's)
_OVERRIDES = {
    "bits": "bits",
    "rho": "rho",
    **{s.dest: s.engine for s in SETTINGS if s.flag and s.engine and "." not in s.engine},
}

#: MPC flags (parsed name -> MPCConfig field) that override the file's MPC settings
_MPC_FLAGS = {
    "u_max": "u_max",
    "x0": "x0",
    "x_ref": "x_ref",
    "x_max": "x_max",
    "q_diag": "Q",
    "r_diag": "R",
    **{s.dest: s.engine.split(".", 1)[1] for s in SETTINGS if s.flag and s.engine and s.engine.startswith("mpc.")},
}

#: quantizer flags (parsed name -> QuantizerSpec field) that override the file's quantizer
_QUANT_FLAGS = {
    s.dest: s.engine.split(".", 1)[1] for s in SETTINGS if s.flag and s.engine and s.engine.startswith("quantizer.")
}


def config_from_file(args: argparse.Namespace, defaults: argparse.Namespace, mpc: bool) -> SweepConfig:
    """The SweepConfig of ``--config FILE`` (JSON result or TOML), with flags that differ from ``defaults``.

    ``defaults`` is the parsed namespace of the bare command. ``--dither``, ``--range``, ``--limits`` and
    ``--guard`` given with non-default values override the file's quantizer, the MPC flags its MPC settings;
    ``--no-mpc`` switches MPC off. ``--system``/``--A``/``--B`` are refused (the system is the file's).
    """
    import dataclasses
    import json

    from qsid_core import SweepConfig

    path = Path(args.config)
    try:
        text = path.read_text()
    except OSError as exc:
        raise UsageError(f"argument --config: cannot read {str(path)!r}: {exc.strerror or exc}") from None
    try:
        if path.suffix.lower() == ".toml":
            import tomllib

            data = tomllib.loads(text)
        else:
            data = json.loads(text)
    except ValueError as exc:
        raise UsageError(
            f"argument --config: {str(path)!r} is not valid {'TOML' if path.suffix.lower() == '.toml' else 'JSON'} "
            f"({one_line(exc)})"
        ) from None
    cfg = SweepConfig.from_dict(data)
    changes: dict[str, Any] = {}
    for flag, fieldname in _OVERRIDES.items():
        v = getattr(args, flag, None)
        if v != getattr(defaults, flag, None):
            changes[fieldname] = v
    for name, value in given_seeds(args).items():  # typed, else --seed's
        changes.setdefault(name, value)
    q = cfg.quantizer
    qchanges = {k: getattr(args, a) for a, k in _QUANT_FLAGS.items() if getattr(args, a) != getattr(defaults, a)}
    if args.limits is not None:
        qchanges["fixed_range"] = args.limits[0] if len(args.limits) == 1 else args.limits
    if qchanges:
        changes["quantizer"] = dataclasses.replace(q, **qchanges)
    for flag in ("system", "a_text", "b_text"):
        if getattr(args, flag, None) != getattr(defaults, flag, None):
            raise UsageError(
                "argument --config: the system comes from the file; drop --system/--A/--B (or edit the file's system)"
            )
    mchanges = {k: getattr(args, a) for a, k in _MPC_FLAGS.items() if getattr(args, a) != getattr(defaults, a)}
    if "u_max" in mchanges and len(mchanges["u_max"]) == 1:
        mchanges["u_max"] = mchanges["u_max"][0]
    if not mpc:
        changes["mpc"] = None
    elif mchanges:
        from qsid_core import MPCConfig

        changes["mpc"] = dataclasses.replace(cfg.mpc or MPCConfig(), **mchanges)
    cfg = dataclasses.replace(cfg, **changes) if changes else cfg
    from qsid_core import get_system

    check_channels(cfg, get_system(cfg.system))
    return cfg
