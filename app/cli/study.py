"""The engine config of a run from its arguments, for both plant kinds (:func:`engine_config`).

A linear plant's: the options (:func:`app.cli.runner.config`), or ``qsid sweep --config FILE``, a saved study
(a JSON result or a TOML file) as a SweepConfig (:func:`config_from_file`). A nonlinear ``--system`` (a preset of
``qsid systems`` or a plant file naming a ``vector_field``; :func:`wanted`) gives a
:class:`~qsid_core.studies.KoopmanConfig` (:func:`koopman_config`) and the same commands run the nonlinear study.
Where an option is not typed, the nonlinear defaults apply: 2000 runs x 100 steps, 20 realizations, b = 2..8, MPC
horizon 20 and 200 closed-loop steps (``KoopmanConfig()``, ``KOOPMAN_MPC``); the JSON states what ran.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.settings.cli import add_setting_options, given_seeds
from app.settings.schema import NONLINEAR_GROUP, SETTINGS, nonlinear_settings

from .runner import UsageError, check_channels, config, one_line, system_from_args

if TYPE_CHECKING:
    from qsid_core import SweepConfig
    from qsid_core.studies import KoopmanConfig

    from .runner import Reporter

__all__ = [
    "NONLINEAR_ONLY",
    "SUPPORTED",
    "add_nonlinear_options",
    "config_from_file",
    "engine_config",
    "koopman_config",
    "nonlinear_result",
    "wanted",
]


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


def engine_config(args: argparse.Namespace, mpc: bool) -> SweepConfig | KoopmanConfig:
    """The run's engine config, chosen by the plant's kind: a nonlinear ``--system``'s :func:`koopman_config`
    (``--no-mpc`` read from ``args``), else the linear options' (with the closed loops when ``mpc``)."""
    if wanted(args):
        return koopman_config(args)
    return config(args, system_from_args(args), mpc)


def nonlinear_result(args: argparse.Namespace, rep: Reporter) -> dict[str, Any]:
    """The JSON of a nonlinear plant's whole study (``qsid sweep`` and ``qsid bits`` of a nonlinear ``--system``)."""
    from qsid_core.studies import Study

    cfg = koopman_config(args)
    cfg.dictionary()  # a bad --lifting is reported before anything runs
    rep.stage(
        f"nonlinear sweep of {cfg.plant().name}: {cfg.trajectories} x {cfg.steps}, lifting {cfg.lifting}, "
        f"{len(cfg.bits)} word lengths x {cfg.realizations} realizations"
    )
    return Study(cfg).run().to_dict()
