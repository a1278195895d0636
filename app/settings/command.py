"""The ``qsid sweep`` command line that reproduces a :class:`~qsid_core.SweepConfig` (the dashboard's
"As a command"), written from the settings table: every setting with a ``flag`` and an ``engine`` path is
written the same way (:func:`_schema_args`); the few whose flag is not one setting's value (the system,
``--bits``, ``--limits``, the MPC's lists, ``--disturbance``) are written here by hand.

Only settings that differ from the engine's defaults are written, numbers exactly
(``repr``), list values as ``--flag=value`` (a value may start with '-'). Parsing
the line with :func:`app.cli.build_parser` and :func:`app.cli.runner.config`
gives back an equal config (tested round trip). Both front ends use this module
(the CLI's ``--help`` examples, the dashboard's *As a command*), so neither imports the other.

A nonlinear plant's config (:class:`~qsid_core.studies.KoopmanConfig`) is written by the same
:func:`sweep_argv` from the table's ``nonlinear`` paths: only values that differ from ``KoopmanConfig()`` and its MPC
:data:`~qsid_core.studies.KOOPMAN_MPC`, the system, ``--bits``, ``--limits`` and the MPC's lists by hand; parsing
the line with :func:`app.cli.study.koopman_config` gives back an equal config (tested).
"""

from __future__ import annotations

import shlex
from typing import TYPE_CHECKING, Any

from .schema import SETTINGS

if TYPE_CHECKING:
    from collections.abc import Iterable

    from qsid_core import LTISystem, SweepConfig
    from qsid_core.studies import KoopmanConfig

__all__ = [
    "sweep_argv",
    "sweep_command",
    "bits_command",
    "budget_command",
    "system_text",
    "bits_spec",
    "floats_spec",
    "limits_spec",
    "flag_text",
]


def limits_spec(pairs: Iterable[tuple[float, float]]) -> str:
    """Fixed ranges as the ``--limits`` text (inverse of the parser's type)."""
    return ";".join(f"{lo!r},{hi!r}" for lo, hi in pairs)


def floats_spec(values: Iterable[float]) -> str:
    """Numbers as a comma list, exactly (``repr``), for the command a dashboard shows."""
    return ",".join(repr(float(v)) for v in values)


def bits_spec(bits: Iterable[int]) -> str:
    """Word lengths as the ``--bits`` text (``(1, ..., 16)`` -> ``"1:16"``)."""
    b = list(bits)
    if len(b) > 1 and b == list(range(b[0], b[-1] + 1)):
        return f"{b[0]}:{b[-1]}"
    return ",".join(map(str, b))


def _at(cfg: Any, path: str) -> Any:
    """The value at a dotted ``engine`` path of a SweepConfig (MPC off: MPCConfig()'s)."""
    from qsid_core import MPCConfig

    obj = cfg
    for part in path.split("."):
        obj = getattr(obj, part) if obj is not None else getattr(MPCConfig(), part)
    return obj


#: The MPC's settings written by hand (a list, or a flag whose value is not the setting's).
_MPC_LISTS = (("--u-max", "u_max"), ("--x0", "x0"), ("--Q", "Q"), ("--R", "R"), ("--Qf", "Qf"))


def flag_text(v: Any) -> str:
    """A setting's value as a command line flag's text (a tuple comma-separated, floats exactly)."""
    if isinstance(v, tuple):
        return ",".join(repr(x) if isinstance(x, float) else str(x) for x in v)
    return repr(v) if isinstance(v, float) else str(v)


def _schema_args(cfg: SweepConfig) -> list[str]:
    """``--flag=value`` for every generated option whose engine value differs from the engine's default."""
    from qsid_core import SweepConfig

    d = SweepConfig()
    out: list[str] = []
    for s in SETTINGS:
        if s.flag is None or s.engine is None or (s.engine.startswith("mpc.") and cfg.mpc is None):
            continue
        v, dv = _at(cfg, s.engine), _at(d, s.engine)
        if v == dv:
            continue
        if s.type is bool:
            out.append(s.flag if v else f"--no-{s.flag[2:]}")
        elif v is not None:
            out.append(f"{s.flag}={flag_text(v)}")
    return out


def system_text(M: Iterable[Iterable[float]]) -> str:
    """A matrix as the ``--A``/``--B`` text: rows separated by '; ', entries exact."""
    return "; ".join(" ".join(repr(float(v)) for v in row) for row in M)


def _system_args(system: LTISystem, system_source: str | None) -> list[str]:
    from qsid_core import PRESETS

    if system_source is not None:
        return [f"--system={system_source}"]
    if system.name in PRESETS:
        return [] if system.name == "dc-motor" else [f"--system={system.name}"]
    return [f"--A={system_text(system.A)}", f"--B={system_text(system.B)}"]


def _mpc_args(cfg: SweepConfig, system: LTISystem) -> list[str]:
    from qsid_core import MPCConfig

    m, d = cfg.mpc, MPCConfig()
    if m is None:
        return ["--no-mpc"]
    out: list[str] = []
    if m.u_max != d.u_max:
        out.append(f"--u-max={floats_spec(m.u_max if isinstance(m.u_max, tuple) else (m.u_max,))}")
    if m.reference is not None and not isinstance(m.reference, str):
        raise ValueError(
            "the command line gives a sampled reference as a CSV file: write it and use --reference FILE.csv"
        )
    if m.disturbance:
        out.append(
            f"--disturbance={m.disturbance!r}" + ("" if m.disturbance_kind == "gaussian" else f":{m.disturbance_kind}")
        )
    if m.feedback_bits is not None:
        out.append(f"--feedback-bits={m.feedback_bits}")
    if m.verify_steps is None:
        raise ValueError("the command line has no flag for switching the closed-loop verdicts off")
    for flag, v in (
        ("--x0", m.x0),
        ("--x-ref", m.x_ref),
        ("--x-max", m.x_max),
        ("--terminal-box", m.xf_max),
        ("--Qf", m.Qf),
        ("--Q", m.Q),
        ("--R", m.R),
    ):
        if v is not None:  # MPCConfig's checks turn numbers into tuples
            out.append(f"{flag}={floats_spec(v if isinstance(v, tuple) else (v,))}")
    unsupported = [k for k in ("eps", "max_iter") if getattr(m, k) != getattr(d, k)]
    if unsupported:
        raise ValueError(f"the command line has no flag for MPC setting(s) {', '.join(unsupported)}")
    return out


def sweep_argv(cfg: SweepConfig | KoopmanConfig, system_source: str | None = None) -> list[str]:
    """``qsid sweep`` arguments (after ``sweep``) that rebuild ``cfg``, of either plant kind.

    Parameters
    ----------
    cfg : SweepConfig or KoopmanConfig
        With ``system`` an :class:`~qsid_core.plant.systems.LTISystem` (or a preset name); a nonlinear plant by
        its preset's name or plant file.
    system_source : str, optional
        Give ``--system`` this way (a file name); default: the preset's name, or an
        inline ``--A``/``--B`` for any other system (a linear plant's).
    """
    from qsid_core import SweepConfig, get_system
    from qsid_core.studies import KoopmanConfig

    if isinstance(cfg, KoopmanConfig):
        return _koopman_argv(cfg)

    system = get_system(cfg.system)
    d, q = SweepConfig(mpc=None), cfg.quantizer
    out = _system_args(system, system_source)
    if cfg.bits != d.bits:
        out.append(f"--bits={bits_spec(cfg.bits)}")
    out += _schema_args(cfg)
    if q.fixed_range is not None:
        out.append(f"--limits={limits_spec(q.fixed_range)}")
    out += _mpc_args(cfg, system)
    if cfg.rho is not None:
        out.append(f"--rho={cfg.rho!r}")
    return out


def sweep_command(cfg: SweepConfig | KoopmanConfig, system_source: str | None = None) -> str:
    """The whole shell line ``qsid sweep ...`` (quoted for a POSIX shell)."""
    return shlex.join(["qsid", "sweep", *sweep_argv(cfg, system_source)])


def _koopman_argv(cfg: KoopmanConfig) -> list[str]:
    """``qsid sweep`` arguments of a nonlinear plant's ``cfg`` (a nonlinear preset by name): its settings by their
    ``nonlinear`` paths, only those that differ from ``KoopmanConfig()`` and its MPC :data:`~qsid_core.studies.KOOPMAN_MPC`."""
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


def bits_command(
    cfg: SweepConfig, target: float = 0.95, cost_gap: float = 0.01, system_source: str | None = None
) -> str:
    """The shell line ``qsid bits ...`` for ``cfg`` and the answer's thresholds (defaults left out).

    The loop length is always written: without ``--mpc-steps`` ``qsid bits`` chooses it from the plant.
    """
    extra = ([] if target == 0.95 else [f"--target={target!r}"]) + (
        [] if cost_gap == 0.01 else [f"--cost-gap={cost_gap!r}"]
    )
    argv = sweep_argv(cfg, system_source)
    if cfg.mpc is not None and not any(a.startswith("--mpc-steps") for a in argv):
        argv.append(f"--mpc-steps={cfg.mpc.steps}")
    return shlex.join(["qsid", "bits", *argv, *extra])


#: Flags a budget refuses (it sets the runs and sends every channel at b): left out of its line.
_NOT_IN_BUDGET = ("--trajectories", "--input-bits", "--state-bits")


def budget_command(argv: list[str], total_bits: float, bits_per_sample: int | None = None) -> str:
    """The shell line ``qsid budget ...`` of a study's ``qsid sweep`` arguments ``argv`` (:func:`sweep_argv`, or a
    nonlinear plant's) at ``total_bits``: the runs and the word length per channel are the budget's, so their
    flags are left out; with ``bits_per_sample``, the line of the per-channel allocation."""
    kept = [a for a in argv if a.split("=", 1)[0] not in _NOT_IN_BUDGET]
    extra = [] if bits_per_sample is None else [f"--bits-per-sample={int(bits_per_sample)}"]
    return shlex.join(["qsid", "budget", *kept, f"--total-bits={total_bits!r}", *extra])
