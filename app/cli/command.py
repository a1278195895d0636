"""The ``qsid sweep`` command line that reproduces a :class:`~qsid_core.SweepConfig` (the dashboard's
"As a command").

Only settings that differ from the parser's defaults are written, numbers exactly
(``repr``), list values as ``--flag=value`` (a value may start with '-'). Parsing
the line with :func:`app.cli.build_parser` and :func:`app.cli.runner.config`
gives back an equal config (tested round trip).
"""

from __future__ import annotations

import shlex
from typing import TYPE_CHECKING

from .parser import bits_spec, floats_spec, limits_spec

if TYPE_CHECKING:
    from collections.abc import Iterable

    from qsid_core import LTISystem, SweepConfig

__all__ = ["sweep_argv", "sweep_command", "bits_command", "system_text"]


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
    if m.horizon != d.horizon:
        out.append(f"--horizon={m.horizon}")
    if m.steps != d.steps:
        out.append(f"--mpc-steps={m.steps}")
    if m.u_max != d.u_max:
        out.append(f"--u-max={floats_spec(m.u_max if isinstance(m.u_max, tuple) else (m.u_max,))}")
    if m.reference is not None:
        if not isinstance(m.reference, str):
            raise ValueError(
                "the command line gives a sampled reference as a CSV file: write it and use --reference FILE.csv"
            )
        out.append(f"--reference={m.reference}")
    if m.tracking != d.tracking:
        out.append(f"--tracking={m.tracking}")
    if m.disturbance:
        out.append(
            f"--disturbance={m.disturbance!r}" + ("" if m.disturbance_kind == "gaussian" else f":{m.disturbance_kind}")
        )
    if m.feedback_bits is not None:
        out.append(f"--feedback-bits={m.feedback_bits}")
    if m.feedback_noise:
        out.append(f"--feedback-noise={m.feedback_noise!r}")
    if m.loop_seed != d.loop_seed:
        out.append(f"--loop-seed={m.loop_seed}")
    if m.verify_steps != d.verify_steps:
        if m.verify_steps is None:
            raise ValueError("the command line has no flag for switching the closed-loop verdicts off")
        out.append(f"--verify-steps={m.verify_steps}")
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


def sweep_argv(cfg: SweepConfig, system_source: str | None = None) -> list[str]:
    """``qsid sweep`` arguments (after ``sweep``) that rebuild ``cfg``.

    Parameters
    ----------
    cfg : SweepConfig
        With ``system`` an :class:`~qsid_core.plant.systems.LTISystem` (or a preset name).
    system_source : str, optional
        Give ``--system`` this way (a file name); default: the preset's name, or an
        inline ``--A``/``--B`` for any other system.
    """
    from qsid_core import SweepConfig, get_system

    system = get_system(cfg.system)
    d, q, dq = SweepConfig(mpc=None), cfg.quantizer, SweepConfig(mpc=None).quantizer
    out = _system_args(system, system_source)
    if cfg.bits != d.bits:
        out.append(f"--bits={bits_spec(cfg.bits)}")
    for flag, v, dv in (
        ("--realizations", cfg.realizations, d.realizations),
        ("--trajectories", cfg.trajectories, d.trajectories),
        ("--steps", cfg.steps, d.steps),
        ("--data-seed", cfg.data_seed, d.data_seed),
        ("--dither-seed", cfg.dither_seed, d.dither_seed),
        ("--range", q.range_mode, dq.range_mode),
        ("--dither", q.dither, dq.dither),
        ("--estimator", cfg.estimator, d.estimator),
    ):
        if v != dv:
            out.append(f"{flag}={v}")
    if cfg.input_amplitude != d.input_amplitude:
        out.append(f"--input-amplitude={cfg.input_amplitude!r}")
    if q.fixed_range is not None:
        out.append(f"--limits={limits_spec(q.fixed_range)}")
    if q.guard != dq.guard:
        out.append("--guard" if q.guard else "--no-guard")
    if cfg.input_bits is not None:
        ib = cfg.input_bits
        out.append(f"--input-bits={','.join(map(str, ib)) if isinstance(ib, tuple) else ib}")
    # SweepConfig's checks turn state_bits and noise into tuples
    state_bits, noise = cfg.state_bits, cfg.noise
    assert (state_bits is None or isinstance(state_bits, tuple)) and isinstance(noise, tuple)
    if state_bits is not None:
        out.append(f"--state-bits={','.join(map(str, state_bits))}")
    if any(v > 0 for v in noise):
        out.append(f"--noise={floats_spec(noise)}")
    if cfg.noise_known:
        out.append("--noise-known")
    out += _mpc_args(cfg, system)
    if cfg.theta != d.theta:
        out.append(f"--theta={cfg.theta!r}")
    if cfg.rho is not None:
        out.append(f"--rho={cfg.rho!r}")
    return out


def sweep_command(cfg: SweepConfig, system_source: str | None = None) -> str:
    """The whole shell line ``qsid sweep ...`` (quoted for a POSIX shell)."""
    return shlex.join(["qsid", "sweep", *sweep_argv(cfg, system_source)])


def bits_command(
    cfg: SweepConfig, target: float = 0.95, cost_gap: float = 0.01, system_source: str | None = None
) -> str:
    """The shell line ``qsid bits ...`` for ``cfg`` and the answer's thresholds (defaults left out)."""
    extra = ([] if target == 0.95 else [f"--target={target!r}"]) + (
        [] if cost_gap == 0.01 else [f"--cost-gap={cost_gap!r}"]
    )
    return shlex.join(["qsid", "bits", *sweep_argv(cfg, system_source), *extra])
