"""The ``qsid sweep`` line that reproduces a nonlinear sweep (:class:`~qsid_core.studies.KoopmanConfig`): the
dashboard's *As a command* for a nonlinear plant, written from the settings table's ``nonlinear`` paths as
:mod:`app.settings.command` writes a linear one from the ``engine`` paths.

Only values that differ from the nonlinear run's defaults (``KoopmanConfig()``, its MPC
:data:`~qsid_core.studies.KOOPMAN_MPC`) are written, numbers exactly; the system, ``--bits``, ``--limits`` and
the MPC's lists (``--u-max``, ``--x0``, ``--Q``, ``--R``, ``--Qf``) by hand. Parsing the line with
:func:`app.cli.build_parser` and :func:`app.cli.study.koopman_config` gives back an equal config (tested).
"""

from __future__ import annotations

import shlex
from typing import TYPE_CHECKING, Any

from .command import bits_spec, flag_text, floats_spec, limits_spec
from .schema import SETTINGS

if TYPE_CHECKING:
    from qsid_core.studies import KoopmanConfig

__all__ = ["koopman_argv", "koopman_command"]

#: The MPC's settings written by hand (a list, or a flag whose value is not the setting's).
_MPC_LISTS = (("--u-max", "u_max"), ("--x0", "x0"), ("--Q", "Q"), ("--R", "R"), ("--Qf", "Qf"))


def _at(obj: Any, path: str) -> Any:
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def koopman_argv(cfg: KoopmanConfig) -> list[str]:
    """``qsid sweep`` arguments (after ``sweep``) that rebuild ``cfg`` (a nonlinear preset by name)."""
    from qsid_core.studies import KOOPMAN_MPC, KoopmanConfig

    if not isinstance(cfg.system, str):
        raise ValueError("the command line names a nonlinear plant by preset or plant file, not a Python object")
    d = KoopmanConfig()
    out = [f"--system={cfg.system}"]
    if cfg.bits != d.bits:
        out.append(f"--bits={bits_spec(cfg.bits)}")
    for s in SETTINGS:
        path = s.nonlinear
        if s.flag is None or path is None or path == "system" or (path.startswith("mpc.") and cfg.mpc is None):
            continue
        v = _at(cfg, path)
        dv = _at(KOOPMAN_MPC, path.removeprefix("mpc.")) if path.startswith("mpc.") else _at(d, path)
        if v == dv or v is None:
            continue
        out.append((s.flag if v else f"--no-{s.flag[2:]}") if s.type is bool else f"{s.flag}={flag_text(v)}")
    if cfg.quantizer.fixed_range is not None:
        out.append(f"--limits={limits_spec(cfg.quantizer.fixed_range)}")
    if cfg.mpc is None:
        return [*out, "--no-mpc"]
    for flag, name in _MPC_LISTS:
        v, dv = getattr(cfg.mpc, name), getattr(KOOPMAN_MPC, name)
        if v is not None and v != dv:
            out.append(f"{flag}={floats_spec(v if isinstance(v, tuple) else (v,))}")
    return out


def koopman_command(cfg: KoopmanConfig) -> str:
    """The whole shell line ``qsid sweep ...`` (quoted for a POSIX shell)."""
    return shlex.join(["qsid", "sweep", *koopman_argv(cfg)])
