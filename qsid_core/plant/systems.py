"""Reference systems (presets) and custom system files.

A :class:`~qsid_core.plant.lti.LTISystem` is the *true* discrete-time plant ``x+ = A x + B u`` together
with the letter's default regulation task (initial state ``x0`` and the MPC
weights ``Q`` and ``R``).

Presets
-------
``dc-motor``
    DC motor with load, the letter's printed discrete matrices (eq. "DC Motor
    with Load", Section V-A). They are the zero-order-hold discretisation of the
    physical model with J=0.01, c=0.1, K=0.01, Ke=0.01, r=1, L=0.5 at a sample
    time of **1 s**, cut to three decimals (truncated, e.g. 0.0999 is printed
    0.099, 0.0169 as 0.016) -- although the letter also says
    "1000 sampling periods (i.e., 10 seconds per trajectory)", the printed
    matrices are those of 1 s sampling (see :func:`dc_motor_physical`, which
    reproduces them to the printed digits).
``boeing747``
    Boeing 747 longitudinal dynamics at 40 000 ft and 774 ft/s, sampled at 1 s
    (Section V-B, after Goel and Hassibi).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ConfigError, SystemDefinitionError, check_float, short_repr
from ..validate import MAX_MAGNITUDE
from .lti import LTISystem
from .nonlinear import NONLINEAR_PRESETS
from .plantfile import read_plant_table

__all__ = ["PRESETS", "dc_motor", "dc_motor_physical", "boeing747", "get_system", "load_system", "system_from_dict"]


def dc_motor() -> LTISystem:
    """The letter's DC motor with load (3 states, 2 inputs), printed matrices, 1 s sampling.

    States: shaft angle, shaft speed, armature current; inputs: voltage, load torque.
    Defaults from the letter: x0 = [1, 0, 0], Q = diag(1, 0.1, 0.1), R = diag(1, 1).
    """
    A = [[1.000, 0.099, 0.041], [0.0, 0.0, 0.016], [0.0, 0.0, 0.135]]
    B = [[0.048, 8.996], [0.083, 9.991], [0.864, -0.083]]
    return LTISystem(
        "dc-motor",
        A,
        B,
        x0=[1.0, 0.0, 0.0],
        Q=[1.0, 0.1, 0.1],
        R=[1.0, 1.0],
        dt=1.0,
        description="DC motor with load, 3 states, 2 inputs (letter's printed A, B at 1 s)",
        state_names=("angle", "speed", "current"),
        input_names=("voltage", "torque"),
    )


def dc_motor_physical(
    dt: float = 1.0,
    *,
    J: float = 0.01,
    c: float = 0.1,
    K: float = 0.01,
    Ke: float = 0.01,
    r: float = 1.0,
    L: float = 0.5,
) -> LTISystem:
    """DC motor with load from its physical parameters, zero-order hold at ``dt`` seconds.

    Continuous model (letter, eq. "Motor"): x1' = x2, x2' = (K x3 - c x2 + u2)/J,
    x3' = (u1 - r x3 - Ke x2)/L. Discretised with python-control's ``c2d``.
    With the defaults it reproduces the printed matrices of :func:`dc_motor`
    to their three printed decimals (the letter truncates: max difference < 1e-3).
    """
    for nm, v in dict(dt=dt, J=J, L=L, c=c, K=K, Ke=Ke, r=r).items():
        try:
            check_float(nm, v, 0.0, MAX_MAGNITUDE, lo_open=nm in ("dt", "J", "L"))
        except ConfigError as exc:
            raise SystemDefinitionError(str(exc)) from None
    Ac = np.array([[0.0, 1.0, 0.0], [0.0, -c / J, K / J], [0.0, -Ke / L, -r / L]])
    Bc = np.array([[0.0, 0.0], [0.0, 1.0 / J], [1.0 / L, 0.0]])
    Ad, Bd = _zoh(Ac, Bc, dt)  # python-control's c2d(..., method="zoh")
    return LTISystem(
        "dc-motor-physical",
        Ad,
        Bd,
        x0=[1.0, 0.0, 0.0],
        Q=[1.0, 0.1, 0.1],
        R=[1.0, 1.0],
        dt=dt,
        description=f"DC motor with load from physical parameters, ZOH at {dt:g} s",
        state_names=("angle", "speed", "current"),
        input_names=("voltage", "torque"),
    )


def boeing747() -> LTISystem:
    """The letter's Boeing 747 longitudinal dynamics (4 states, 2 inputs), 1 s sampling.

    Defaults from the letter: x0 = [1, 1, 0, 0], Q = diag(1, 0.1, 0.1, 0.1), R = diag(1, 1).
    """
    A = [
        [0.99, 0.03, -0.02, -0.32],
        [0.01, 0.47, 4.70, 0.00],
        [0.02, -0.06, 0.40, 0.00],
        [0.01, -0.04, 0.72, 0.99],
    ]
    B = [[0.01, 0.99], [-3.44, 1.66], [-0.83, 0.44], [-0.47, 0.25]]
    return LTISystem(
        "boeing747",
        A,
        B,
        x0=[1.0, 1.0, 0.0, 0.0],
        Q=[1.0, 0.1, 0.1, 0.1],
        R=[1.0, 1.0],
        dt=1.0,
        description="Boeing 747 longitudinal flight, 4 states, 2 inputs (letter, 1 s)",
        state_names=("u", "w", "q", "theta"),
        input_names=("elevator", "thrust"),
    )


def _zoh(Ac: ArrayLike, Bc: ArrayLike, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation: ``expm([[Ac, Bc], [0, 0]] dt) = [[Ad, Bd], [0, I]]``."""
    from scipy.linalg import expm

    Ac, Bc = np.asarray(Ac, dtype=float), np.asarray(Bc, dtype=float)
    n, m = Bc.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = Ac, Bc
    E = expm(M * dt)
    return E[:n, :n], E[:n, n:]


def dc_motor_fast() -> LTISystem:
    """:func:`dc_motor_physical` sampled at 0.05 s: the same motor, transients over many samples."""
    s = dc_motor_physical(0.05)
    return LTISystem(
        "dc-motor-50ms",
        s.A,
        s.B,
        x0=s.x0,
        Q=s.Q,
        R=s.R,
        dt=0.05,
        description="DC motor with load from physical parameters, ZOH at 0.05 s (many-step transients)",
        state_names=s.state_names,
        input_names=s.input_names,
    )


def inverted_pendulum() -> LTISystem:
    """Inverted pendulum on a cart, linearised about upright, ZOH at 0.05 s (open-loop unstable).

    Ogata, *Modern Control Engineering*, 5th ed., Example 12-5 (cart mass M = 2 kg,
    pendulum mass m = 0.1 kg, length l = 0.5 m, g = 9.81 m/s^2):
    ``theta'' = (M + m) g / (M l) theta - u / (M l)``, ``x'' = -m g / M theta + u / M``.
    States: angle [rad], angular rate, cart position [m], cart velocity; input: force [N].
    Its unstable pole e^{4.54 * 0.05} = 1.255 needs more than log2 1.255 = 0.33 bits per
    sample through any quantized feedback channel (data-rate theorem). Open loop the data
    grow as 1.255^t: use many short training runs (``--trajectories 1000 --steps 15``: the
    MPC then works from b = 8 on). x0 = 0.02 rad tilt (with
    the default ``|u| <= 1`` N the upright can be caught from there), Q = diag(10, 1, 1, 1), R = 1.
    """
    M, m, l, g = 2.0, 0.1, 0.5, 9.81
    Ac: list[list[float]] = [[0, 1, 0, 0], [(M + m) * g / (M * l), 0, 0, 0], [0, 0, 0, 1], [-m * g / M, 0, 0, 0]]
    Bc: list[list[float]] = [[0], [-1 / (M * l)], [0], [1 / M]]
    A, B = _zoh(Ac, Bc, 0.05)
    return LTISystem(
        "inverted-pendulum",
        A,
        B,
        x0=[0.02, 0.0, 0.0, 0.0],
        Q=[10.0, 1.0, 1.0, 1.0],
        R=[1.0],
        dt=0.05,
        description="inverted pendulum on a cart (Ogata Ex. 12-5), ZOH at 0.05 s, open-loop unstable",
        state_names=("angle", "rate", "position", "velocity"),
        input_names=("force",),
    )


def mass_spring_damper() -> LTISystem:
    """A lightly damped mass-spring-damper, ZOH at 0.1 s (slow, oscillating transients).

    m x'' + c x' + k x = u with m = 1 kg, c = 0.2 N s/m, k = 1 N/m (damping ratio 0.1;
    e.g. Ogata, *Modern Control Engineering*, Sec. 2-3). States: position [m],
    velocity; input: force [N]. x0 = [1, 0], Q = I, R = 1.
    """
    A, B = _zoh([[0.0, 1.0], [-1.0, -0.2]], [[0.0], [1.0]], 0.1)
    return LTISystem(
        "mass-spring-damper",
        A,
        B,
        x0=[1.0, 0.0],
        Q=[1.0, 1.0],
        R=[1.0],
        dt=0.1,
        description="mass-spring-damper, damping ratio 0.1, ZOH at 0.1 s",
        state_names=("position", "velocity"),
        input_names=("force",),
    )


PRESETS = {
    "dc-motor": dc_motor,
    "boeing747": boeing747,
    "dc-motor-physical": dc_motor_physical,
    "dc-motor-50ms": dc_motor_fast,
    "inverted-pendulum": inverted_pendulum,
    "mass-spring-damper": mass_spring_damper,
}


def system_from_dict(d: Mapping[str, Any], name: str = "custom") -> LTISystem:
    """Build an :class:`LTISystem` from a mapping with keys A, B and optional x0, Q, R, dt, name.

    Q and R may be given as full matrices or as lists of diagonal entries.
    """
    if not isinstance(d, Mapping):
        raise SystemDefinitionError("a system file must hold a table/object with keys A and B")
    unknown = set(d) - {"A", "B", "x0", "Q", "R", "dt", "name", "description"}
    if unknown:
        raise SystemDefinitionError(
            f"unknown key(s) {sorted(unknown)} in system definition; allowed: A, B, x0, Q, R, dt, name, description"
        )
    for key in ("A", "B"):
        if key not in d:
            raise SystemDefinitionError(f"system definition is missing {key!r} (needs A and B)")
    for key in ("x0", "Q", "R"):
        if key in d and d[key] is None:
            raise SystemDefinitionError(f"{key} is empty (null); leave it out to use the default")
    return LTISystem(
        d.get("name", name),
        d["A"],
        d["B"],
        x0=d.get("x0"),
        Q=d.get("Q"),
        R=d.get("R"),
        dt=d.get("dt", 1.0),
        description=d.get("description", "custom system"),
    )


def load_system(path: str | Path) -> LTISystem:
    """Read a custom system from a ``.toml`` or ``.json`` file.

    The file holds ``A`` (n x n), ``B`` (n x m) and optionally ``x0`` (n), ``Q``
    (n x n or n diagonal entries), ``R`` (m x m or m entries) and ``dt``.

    Raises
    ------
    SystemDefinitionError
        The file cannot be read as a plant file (:func:`~qsid_core.plant.plantfile.read_plant_table`: missing,
        a directory, a FIFO, a loop of links, binary, nested too deeply ...) or does not define a system.
    """
    if not isinstance(path, (str, Path)):
        raise SystemDefinitionError(f"system file must be a path; got {short_repr(path)}")
    return system_from_dict(read_plant_table(path), name=Path(path).stem)


def get_system(name_or_path: str | Path | LTISystem) -> LTISystem:
    """A preset by name (see :data:`PRESETS`), or a system file path, or pass an LTISystem through."""
    if isinstance(name_or_path, LTISystem):
        return name_or_path
    if not isinstance(name_or_path, (str, Path)):
        raise SystemDefinitionError(
            f"system must be a preset name ({', '.join(PRESETS)}), a path to a .toml/.json file or an LTISystem; "
            f"got {short_repr(name_or_path)}"
        )
    key = str(name_or_path)
    if key in PRESETS:
        return PRESETS[key]()
    if key.strip().lower() in NONLINEAR_PRESETS:
        raise SystemDefinitionError(
            f"system {short_repr(key)} is a nonlinear plant: this needs a linear one ({', '.join(PRESETS)}); "
            "nonlinear plants run as Koopman/EDMD sweeps (KoopmanConfig)"
        )
    if key.lower().endswith((".toml", ".json")) or _exists(key):
        return load_system(key)
    raise SystemDefinitionError(
        f"unknown system {short_repr(key)}: not a preset ({', '.join(PRESETS)}; nonlinear: "
        f"{', '.join(NONLINEAR_PRESETS)}) and not an existing .toml/.json file"
    )


def _exists(path: str) -> bool:
    """``Path(path).exists()`` that says False for names the OS refuses (too long, NUL byte)."""
    try:
        return Path(path).exists()
    except (OSError, ValueError):
        return False
