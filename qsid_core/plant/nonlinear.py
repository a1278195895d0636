"""Nonlinear plants: a continuous-time vector field sampled by one classical RK4 step per sample.

A :class:`NonlinearSystem` is ``xdot = f(x, u)`` with a zero-order hold on ``u`` over each sample of
``dt`` seconds; the discrete plant is one classical Runge-Kutta (RK4) step::

    k1 = f(x, u), k2 = f(x + dt/2 k1, u), k3 = f(x + dt/2 k2, u), k4 = f(x + dt k3, u)
    x+ = x + dt/6 (k1 + 2 k2 + 2 k3 + k4)

Presets (all with ``dt = 0.05``):

``van-der-pol``
    x1' = x2, x2' = mu (1 - x1^2) x2 - x1 + u with mu = 1 (an unstable origin inside a limit cycle).
``duffing``
    x1' = x2, x2' = -0.5 x2 + x1 - x1^3 + u (a saddle at the origin between two stable wells at x1 = +-1).
``pendulum``
    x1' = x2, x2' = -sin x1 - 0.1 x2 + u (a damped pendulum, stable at the origin).

A custom plant is a Python callable ``f(x, u) -> xdot`` vectorised over a batch (``x`` of shape
(runs, n), ``u`` of shape (runs, m), the result of shape (runs, n)); a plant file names it as
``vector_field = "module:function"`` (see :func:`nonlinear_from_dict`); the module may sit beside the file
(:mod:`qsid_core.plant.field_import`).

The training runs of these plants (x0 within the plant's ``amplitude``, runs leaving its sane ``box``
reported) are drawn by :mod:`qsid_core.plant.nonlinear_data`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError, SystemDefinitionError, check_float, check_int, short_repr
from .field_import import resolve_field
from .plantfile import read_plant_table

__all__ = [
    "NONLINEAR_PRESETS",
    "NonlinearSystem",
    "VectorField",
    "get_nonlinear",
    "is_nonlinear",
    "is_nonlinear_file",
    "load_nonlinear",
    "nonlinear_from_dict",
    "rk4_step",
]

#: ``f(x, u) -> xdot`` over a batch: x (runs, n), u (runs, m) -> (runs, n)
VectorField = Callable[[np.ndarray, np.ndarray], np.ndarray]

#: Default sane box ``|x_i| <= SANE_BOX`` of the presets (a run beyond it is reported and left out).
SANE_BOX = 50.0


@dataclass(frozen=True, eq=False)
class NonlinearSystem:
    """A nonlinear plant ``xdot = f(x, u)``, sampled by one RK4 step of ``dt`` with the input held.

    Parameters
    ----------
    name : str
        Short identifier.
    vector_field : callable
        ``f(x, u)`` with x of shape (runs, n) and u of shape (runs, m), returning shape (runs, n).
    n, m : int
        Numbers of states and inputs.
    dt : float, > 0
        Sample time in seconds (one RK4 step per sample).
    x0 : tuple of float, length n
        Initial state of the regulation task.
    Q, R : tuple of float
        Diagonals of the state (length n, >= 0) and input (length m, > 0) weights.
    amplitude : float, > 0
        ``a`` of the training runs' x0 ~ U[-a, a]^n.
    box : float, > 0
        The sane box ``|x_i| <= box``: a run beyond it is reported and left out of the data.
    description : str
    state_names, input_names : tuple of str
    """

    name: str
    vector_field: VectorField
    n: int
    m: int
    dt: float = 0.05
    x0: tuple[float, ...] = ()
    Q: tuple[float, ...] = ()
    R: tuple[float, ...] = ()
    amplitude: float = 2.0
    box: float = SANE_BOX
    description: str = ""
    state_names: tuple[str, ...] = field(default=())
    input_names: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if not callable(self.vector_field):
            raise SystemDefinitionError(
                f"vector field of {self.name!r} must be callable; got {short_repr(self.vector_field)}"
            )
        object.__setattr__(self, "n", check_int("states n", self.n, 1, 20))
        object.__setattr__(self, "m", check_int("inputs m", self.m, 1, 20))
        object.__setattr__(self, "dt", check_float("dt", self.dt, 0.0, 1e6, lo_open=True))
        object.__setattr__(self, "amplitude", check_float("amplitude", self.amplitude, 0.0, 1e6, lo_open=True))
        object.__setattr__(self, "box", check_float("box", self.box, 0.0, 1e12, lo_open=True))
        for nm, k, default, lo in (("x0", self.n, 0.0, None), ("Q", self.n, 1.0, 0.0), ("R", self.m, 0.1, 0.0)):
            v = np.asarray(getattr(self, nm) or [default] * k, dtype=float).reshape(-1)
            if v.size == 1:
                v = np.repeat(v, k)
            if v.size != k or not np.all(np.isfinite(v)):
                raise SystemDefinitionError(f"{nm} of {self.name!r} must have {k} finite entries; got {v.size}")
            if lo is not None and (np.any(v < lo) or (nm == "R" and np.any(v <= 0))):
                raise SystemDefinitionError(f"{nm} of {self.name!r} must be {'> 0' if nm == 'R' else '>= 0'}")
            object.__setattr__(self, nm, tuple(v.tolist()))
        object.__setattr__(self, "state_names", tuple(self.state_names) or tuple(f"x{i + 1}" for i in range(self.n)))
        object.__setattr__(self, "input_names", tuple(self.input_names) or tuple(f"u{i + 1}" for i in range(self.m)))

    def xdot(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """The vector field at a batch, checked: shape (runs, n), finite.

        Raises
        ------
        SystemDefinitionError
            If the callable raises, returns the wrong shape, or returns NaN or inf at a finite state.
        """
        try:
            out = np.asarray(self.vector_field(x, u), dtype=float)
        except Exception as exc:  # any failure of user code becomes one line naming the field
            raise SystemDefinitionError(
                f"vector field of {self.name!r} raised {type(exc).__name__}: {str(exc)[:200]}"
            ) from None
        if out.shape != x.shape:
            raise SystemDefinitionError(
                f"vector field of {self.name!r} returned shape {out.shape}; expected {x.shape} (runs, n)"
            )
        bad = ~np.all(np.isfinite(out), axis=1) & np.all(np.isfinite(x), axis=1)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise SystemDefinitionError(
                f"vector field of {self.name!r} returned NaN or inf at x = {np.round(x[i], 6).tolist()}, "
                f"u = {np.round(u[i], 6).tolist()}"
            )
        return out

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        """One sample: RK4 with the input held, x (runs, n), u (runs, m) -> (runs, n)."""
        return rk4_step(self.xdot, x, u, self.dt)


def rk4_step(f: VectorField, x: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
    """One classical Runge-Kutta step of ``xdot = f(x, u)`` with ``u`` held: shapes (runs, n), (runs, m)."""
    h = 0.5 * dt
    k1 = f(x, u)
    k2 = f(x + h * k1, u)
    k3 = f(x + h * k2, u)
    k4 = f(x + dt * k3, u)
    out: np.ndarray = x + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
    return out


def _van_der_pol(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    x1, x2 = x[:, 0], x[:, 1]
    return np.stack([x2, (1.0 - x1 * x1) * x2 - x1 + u[:, 0]], axis=1)


def _duffing(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    x1, x2 = x[:, 0], x[:, 1]
    return np.stack([x2, -0.5 * x2 + x1 - x1**3 + u[:, 0]], axis=1)


def _pendulum(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    x1, x2 = x[:, 0], x[:, 1]
    return np.stack([x2, -np.sin(x1) - 0.1 * x2 + u[:, 0]], axis=1)


def van_der_pol() -> NonlinearSystem:
    """Van der Pol oscillator, mu = 1, dt = 0.05; regulation from x0 = (2, 0) (on the limit cycle) to 0."""
    return NonlinearSystem(
        "van-der-pol",
        _van_der_pol,
        2,
        1,
        x0=(2.0, 0.0),
        description="Van der Pol oscillator (mu = 1), nonlinear, 2 states, 1 input, RK4 at dt = 0.05",
        state_names=("position", "velocity"),
        input_names=("force",),
    )


def duffing() -> NonlinearSystem:
    """Duffing oscillator, dt = 0.05; regulation from the stable well x0 = (1, 0) to the saddle at 0."""
    return NonlinearSystem(
        "duffing",
        _duffing,
        2,
        1,
        x0=(1.0, 0.0),
        description="Duffing oscillator (double well), nonlinear, 2 states, 1 input, RK4 at dt = 0.05",
        state_names=("position", "velocity"),
        input_names=("force",),
    )


def pendulum() -> NonlinearSystem:
    """Damped pendulum, dt = 0.05; regulation from x0 = (2, 0) (about 115 degrees) to hanging at 0."""
    return NonlinearSystem(
        "pendulum",
        _pendulum,
        2,
        1,
        x0=(2.0, 0.0),
        description="damped pendulum, nonlinear, 2 states, 1 input, RK4 at dt = 0.05",
        state_names=("angle", "rate"),
        input_names=("torque",),
    )


#: The nonlinear presets by name.
NONLINEAR_PRESETS: dict[str, Callable[[], NonlinearSystem]] = {
    "van-der-pol": van_der_pol,
    "duffing": duffing,
    "pendulum": pendulum,
}


def is_nonlinear(name: object) -> bool:
    """Whether ``name`` is a nonlinear preset's name, a nonlinear plant file or a :class:`NonlinearSystem`.

    Raises
    ------
    SystemDefinitionError
        ``name`` is a .toml/.json path where something is that cannot be read as a plant file
        (see :func:`is_nonlinear_file`).
    """
    if isinstance(name, NonlinearSystem):
        return True
    return isinstance(name, str) and (name.strip().lower() in NONLINEAR_PRESETS or is_nonlinear_file(name))


def get_nonlinear(name: str | NonlinearSystem) -> NonlinearSystem:
    """A nonlinear preset by name, a plant file naming a ``vector_field``, or a :class:`NonlinearSystem` passed through.

    Raises
    ------
    ConfigError
        For an unknown name.
    """
    if isinstance(name, NonlinearSystem):
        return name
    if is_nonlinear_file(name):
        return load_nonlinear(name)
    key = str(name).strip().lower()
    if key not in NONLINEAR_PRESETS:
        raise ConfigError(f"unknown nonlinear system {short_repr(name)}; choose from {', '.join(NONLINEAR_PRESETS)}")
    return NONLINEAR_PRESETS[key]()


def nonlinear_from_dict(
    d: Mapping[str, Any], name: str = "custom", folder: str | Path | None = None
) -> NonlinearSystem:
    """A nonlinear plant from a plant file's table (``folder``: the file's, where its module may sit).

    Keys: ``vector_field`` ("module:function", required), ``n``, ``m`` (required), and optional
    ``dt``, ``x0``, ``Q``, ``R``, ``amplitude``, ``box``, ``description``, ``state_names``, ``input_names``.

    Raises
    ------
    SystemDefinitionError
        If a key is missing or unknown, or the function cannot be imported.
    """
    known = {"vector_field", "n", "m", "dt", "x0", "Q", "R", "amplitude", "box", "description", "state_names"}
    known |= {"input_names", "name"}
    extra = sorted(set(d) - known)
    if extra:
        raise SystemDefinitionError(f"unknown key(s) in nonlinear plant {name!r}: {', '.join(extra)}")
    for k in ("vector_field", "n", "m"):
        if k not in d:
            raise SystemDefinitionError(f"nonlinear plant {name!r} needs {k!r}")
    if not isinstance(d["vector_field"], str):
        raise SystemDefinitionError("vector_field must be a string 'module:function'")
    kw = {k: d[k] for k in ("dt", "amplitude", "box", "description") if k in d}
    for k in ("x0", "Q", "R", "state_names", "input_names"):
        if k in d:
            kw[k] = tuple(d[k])
    return NonlinearSystem(str(d.get("name", name)), resolve_field(d["vector_field"], folder), d["n"], d["m"], **kw)


def is_nonlinear_file(path: str | Path) -> bool:
    """Whether ``path`` is an existing .toml/.json plant file that names a ``vector_field``.

    False for a name without that suffix or with nothing at it.

    Raises
    ------
    SystemDefinitionError
        Something is at ``path`` but it cannot be read as a plant file (a directory, a FIFO, a loop of links,
        binary, nested too deeply ...): the line :func:`~qsid_core.plant.plantfile.read_plant_table` gives.
    """
    if not isinstance(path, (str, Path)):
        return False
    p = Path(path)
    if p.suffix.lower() not in (".toml", ".json"):
        return False
    try:
        os.stat(p)
    except (FileNotFoundError, NotADirectoryError):
        return False
    except (OSError, ValueError):  # a loop of links, a name too long, a NUL byte: said by read_plant_table
        pass
    return "vector_field" in read_plant_table(p)


def load_nonlinear(path: str | Path) -> NonlinearSystem:
    """A nonlinear plant from a .toml or .json file (keys of :func:`nonlinear_from_dict`).

    Raises
    ------
    SystemDefinitionError
        Unreadable or malformed file, or a vector field that cannot be imported.
    """
    p = Path(path)
    return nonlinear_from_dict(read_plant_table(p), p.stem, p.parent)
