"""Your own recorded data: quantize it at each word length, identify by LS and BCLS, compare.

No true model is needed: the reference is the LS estimate from the *unquantized* recorded data
(what the quantization takes away), or a given system's ``(A, B)`` when there is one.

Data come as arrays (``x``: runs x (steps + 1) x n, ``u``: runs x steps x m), or from a file:
``.npz`` with arrays ``x`` and ``u`` of those shapes, or ``.csv`` with a header ``run, t, x1..xn,
u1..um`` (one row per run and time step ``t = 0..steps``; the inputs of the last row of a run may be
empty, they are not used).
"""

from __future__ import annotations

import csv
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConfigError, check_int
from ..identification.identify import identify, least_squares, mean_std_of_known, relative_errors
from ..plant.data import Dataset
from ..plant.lti import LTISystem
from ..quantization.moments import Moments, PreparedData, prepare, quantized_moments
from ..quantization.quantize import ERROR_VARIANCE, QuantizerSpec
from .config import parse_bits

__all__ = ["RecordedResult", "dataset_from_arrays", "load_recorded", "identify_recorded", "theorem1_on_data"]


def dataset_from_arrays(x: ArrayLike, u: ArrayLike) -> Dataset:
    """A :class:`Dataset` from recorded arrays, checked.

    Parameters
    ----------
    x : array_like, shape (runs, steps + 1, n) or (steps + 1, n) for one run
    u : array_like, shape (runs, steps, m) or (steps, m)

    Raises
    ------
    ConfigError
        Ragged runs (a list of runs of different lengths), NaN/inf, or shapes that do not fit.
    """
    arrs = []
    for name, a in (("x", x), ("u", u)):
        try:
            arr = np.asarray(a, dtype=float)
        except (ValueError, TypeError):
            raise ConfigError(
                f"{name}: runs of different lengths or entries that are not numbers; every run "
                "needs the same number of steps"
            ) from None
        if arr.ndim == 2:
            arr = arr[None]
        if arr.ndim != 3 or 0 in arr.shape:
            raise ConfigError(
                f"{name} must have shape (runs, {'steps + 1, n' if name == 'x' else 'steps, m'}); got {arr.shape}"
            )
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            r, t, c = (int(v) for v in bad[0])
            raise ConfigError(
                f"{name} has {len(bad)} entries that are NaN or infinite (first: run {r + 1}, "
                f"step {t}, channel {c + 1})"
            )
        arrs.append(arr)
    xa, ua = arrs
    if xa.shape[0] != ua.shape[0]:
        raise ConfigError(f"x has {xa.shape[0]} runs but u has {ua.shape[0]}")
    if xa.shape[1] != ua.shape[1] + 1:
        raise ConfigError(
            f"each run needs steps + 1 states and steps inputs; got {xa.shape[1]} states and "
            f"{ua.shape[1]} inputs per run"
        )
    return Dataset(xa, ua, None, float("nan"))


def _read_csv(p: Path) -> Dataset:
    with p.open(newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ConfigError(f"{p.name} is empty")
    head = [h.strip().lower() for h in rows[0]]
    xs = [h for h in head if h.startswith("x") and h[1:].isdigit()]
    us = [h for h in head if h.startswith("u") and h[1:].isdigit()]
    want = ["run", "t"] + [f"x{i + 1}" for i in range(len(xs))] + [f"u{i + 1}" for i in range(len(us))]
    if head != want or not xs or not us:
        raise ConfigError(f"{p.name}: the columns must be run, t, x1..xn, u1..um (got {', '.join(head)[:200]})")
    n = len(xs)
    runs: dict[str, list[tuple[int, list[float]]]] = {}
    for k, r in enumerate(rows[1:], start=2):
        if not any(c.strip() for c in r):
            continue
        if len(r) != len(head):
            raise ConfigError(f"{p.name}, line {k}: {len(r)} values, the header has {len(head)}")
        try:
            run, t = r[0].strip(), int(r[1])
            vals = [float(c) if c.strip() else float("nan") for c in r[2:]]
        except ValueError:
            raise ConfigError(f"{p.name}, line {k}: not a number ({', '.join(r)[:120]})") from None
        runs.setdefault(run, []).append((t, vals))
    xl, ul = [], []
    for run, items in runs.items():
        items.sort()
        ts = [t for t, _ in items]
        if ts != list(range(len(ts))):
            raise ConfigError(f"{p.name}: run {run!r} must have t = 0, 1, 2, ... without gaps or repeats")
        v = np.array([vals for _, vals in items])
        xl.append(v[:, :n])
        ul.append(v[:-1, n:])
    if len({len(a) for a in xl}) > 1:
        lens = sorted({len(a) - 1 for a in xl})
        raise ConfigError(
            f"{p.name}: runs of different lengths ({', '.join(map(str, lens))} steps); every run "
            "needs the same number of steps"
        )
    return dataset_from_arrays(np.stack(xl), np.stack(ul))


def load_recorded(path: str | os.PathLike[str]) -> Dataset:
    """Recorded data from a ``.npz`` (arrays ``x``, ``u``) or ``.csv`` (``run, t, x1..xn, u1..um``) file.

    Raises
    ------
    ConfigError
        Missing or unreadable file, wrong columns or arrays, ragged runs, NaN.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"data file {str(p)!r} " + ("is a directory" if p.is_dir() else "does not exist"))
    suffix = p.suffix.lower()
    if suffix == ".csv":
        return _read_csv(p)
    if suffix != ".npz":
        raise ConfigError(f"data file {p.name!r}: give a .npz (arrays x, u) or a .csv (run, t, x1..xn, u1..um)")
    try:
        with np.load(p, allow_pickle=False) as z:
            missing = [k for k in ("x", "u") if k not in z.files]
            if missing:
                raise ConfigError(
                    f"{p.name} needs arrays 'x' (runs x (steps+1) x n) and 'u' (runs x steps x m); "
                    f"missing {', '.join(missing)} (has {', '.join(z.files) or 'none'})"
                )
            x, u = z["x"], z["u"]
    except (OSError, ValueError) as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"{p.name} is not a readable .npz file ({exc})") from None
    return dataset_from_arrays(x, u)


@dataclass
class RecordedResult:
    """Errors of LS and BCLS on quantized recorded data against a reference model.

    Attributes
    ----------
    bits : tuple of int
    reference : str
        ``"LS on the unquantized data"`` or the given system's name.
    A_ref, B_ref : ndarray, shapes (n, n), (n, m)
    eps : dict b -> ndarray (n + m,)
    err : dict (estimator, b) -> ndarray (R, 2)
        Relative errors of A and B per realization.
    overload : dict b -> float
    notes : list of str
    theory : dict b -> dict
        Theorem 1's prediction from the data's own second moments (:func:`theorem1_on_data`).
    """

    bits: tuple[int, ...]
    reference: str
    A_ref: np.ndarray
    B_ref: np.ndarray
    eps: dict[int, np.ndarray]
    err: dict[tuple[str, int], np.ndarray]
    overload: dict[int, float]
    runs: int
    steps: int
    notes: list[str] = field(default_factory=list)
    theory: dict[int, dict[str, Any]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data: one row per b with mean/std of each estimator's errors and Theorem 1's prediction."""
        rows = []
        for b in self.bits:
            r = {"bits": b, "eps": self.eps[b].tolist(), "overload_fraction": self.overload[b]}
            for est in ("ls", "bcls"):
                e = self.err[(est, b)]
                r[est] = {
                    k: dict(zip(("mean", "std"), mean_std_of_known(e[:, j]))) for j, k in enumerate(("err_A", "err_B"))
                }
            if b in self.theory:
                r["theorem1"] = self.theory[b]
            rows.append(r)
        return {
            "reference": self.reference,
            "A_ref": self.A_ref.tolist(),
            "B_ref": self.B_ref.tolist(),
            "runs": self.runs,
            "steps": self.steps,
            "results": rows,
            "notes": list(self.notes),
        }


def theorem1_on_data(
    PP: np.ndarray, T: int, A: np.ndarray, B: np.ndarray, eps: ArrayLike, dither: str, overload: float
) -> dict[str, Any]:
    """Theorem 1's LS errors predicted from the data's own ``Sigma = Psi Psi^T / T``, and whether they apply.

    The hypotheses are checked as in :mod:`qsid_core.studies.assumptions`: a dither of known error
    variance (subtractive or tpdf), a stable reference model (``Sigma`` has a limit: spectral radius
    below ``1 - STATIONARITY_MARGIN``), no entry overloaded, and large data per block (Theorem 1's bias
    at least ``LARGE_DATA_RATIO`` times the predicted finite-data fluctuation).

    Parameters
    ----------
    PP : ndarray, shape (n+m, n+m)
        ``Psi Psi^T`` of the unquantized data, summed over the ``T`` samples.
    T : int
    A, B : ndarray, shapes (n, n), (n, m)
        The reference model.
    eps : ndarray, shape (n+m,)
        Cell widths at this b.
    dither : str
    overload : float
        Mean fraction of overloaded entries.

    Returns
    -------
    dict
        ``err_A``, ``err_B`` (predicted relative errors), ``fluctuation_A``, ``fluctuation_B``,
        ``holds_A``, ``holds_B`` and ``why`` (the hypotheses that fail, in words).
    """
    from ..identification.theorem1 import theorem1_prediction
    from .assumptions import LARGE_DATA_RATIO, STATIONARITY_MARGIN, finite_data_fluctuation

    n = A.shape[0]
    G = np.hstack([A, B])
    eps = np.asarray(eps, dtype=float)
    Gp = theorem1_prediction(G, PP / T, eps, dither)
    eA, eB = relative_errors(Gp[:, :n], Gp[:, n:], A, B)
    fA, fB = finite_data_fluctuation(G, PP, eps)
    fA, fB = float(fA / np.linalg.norm(A)), float(fB / np.linalg.norm(B))
    why = []
    if dither not in ERROR_VARIANCE:
        why.append(f"dither {dither} has no signal-independent error variance")
    rho = float(np.abs(np.linalg.eigvals(A)).max())
    if not rho < 1.0 - STATIONARITY_MARGIN:
        why.append(f"Psi Psi^T / T has no limit (spectral radius of the reference A {rho:.6g})")
    if overload > 0:
        why.append(f"{100 * overload:.3g} % of the entries overload")
    common = not why
    large = {"A": eA >= LARGE_DATA_RATIO * fA, "B": eB >= LARGE_DATA_RATIO * fB}
    for blk, e, f in (("A", eA, fA), ("B", eB, fB)):
        if not large[blk]:
            why.append(f"finite data for {blk}^ (bias {e:.3g} < {LARGE_DATA_RATIO:g} x fluctuation {f:.3g})")
    return {
        "err_A": float(eA),
        "err_B": float(eB),
        "fluctuation_A": float(fA),
        "fluctuation_B": float(fB),
        "holds_A": bool(common and large["A"]),
        "holds_B": bool(common and large["B"]),
        "why": why,
    }


def _reference(
    data: Dataset, prep: PreparedData, system: LTISystem | None
) -> tuple[NDArray[np.float64], NDArray[np.float64], str]:
    """The model the errors are measured against: ``system``, or LS on the unquantized data; and its name."""
    if system is not None:
        if system.A.shape[0] != data.n or system.B.shape[1] != data.m:
            raise ConfigError(
                f"system {system.name!r} has {system.n} states and {system.m} inputs; the data have "
                f"{data.n} and {data.m}"
            )
        return system.A, system.B, system.name
    try:
        A_ref, B_ref = least_squares(prep.exact.PP, prep.exact.XP, data.n)
    except ValueError as exc:
        raise ConfigError(f"the unquantized data do not identify a model: {exc}") from None
    return A_ref, B_ref, "LS on the unquantized data"


def _errors(
    bits: Sequence[int], moms: Sequence[Sequence[Moments]], A_ref: NDArray[np.float64], B_ref: NDArray[np.float64]
) -> tuple[dict[tuple[str, int], NDArray[np.float64]], set[str]]:
    """Relative errors of LS and BCLS at each b for every realization (NaN where impossible), and the notes."""
    err: dict[tuple[str, int], NDArray[np.float64]] = {}
    notes: set[str] = set()
    for j, b in enumerate(bits):
        for est in ("ls", "bcls"):
            rows = []
            for mo in (m[j] for m in moms):
                try:
                    idn = identify(mo, est)
                    notes.update([idn.note] if idn.note else [])
                    rows.append(relative_errors(idn.A, idn.B, A_ref, B_ref))
                except ValueError as exc:
                    notes.add(f"b = {b}: {exc}")
                    rows.append((float("nan"), float("nan")))
            err[(est, b)] = np.array(rows)
    return err, notes


def identify_recorded(
    data: Dataset | tuple[ArrayLike, ArrayLike],
    bits: str | int | Sequence[int] = "2:12",
    quantizer: QuantizerSpec | None = None,
    realizations: int = 5,
    dither_seed: int = 1,
    system: LTISystem | None = None,
) -> RecordedResult:
    """Quantize recorded data at each b, identify by LS and BCLS, and compare with a reference model.

    Parameters
    ----------
    data : Dataset or tuple (x, u)
        From :func:`dataset_from_arrays` or :func:`load_recorded`, or the arrays themselves.
    bits : str or sequence of int
        Word lengths (:func:`~qsid_core.studies.config.parse_bits`).
    quantizer : QuantizerSpec, optional
        Dither, range and guard band (default ``QuantizerSpec()``).
    realizations : int
        Dither realizations per b (1 is used without dither).
    dither_seed : int
    system : LTISystem, optional
        A true model to compare with; default the LS estimate from the unquantized data.

    Raises
    ------
    ConfigError
        Bad settings, a system whose shapes do not match the data, or data not rich enough for LS.
    """
    if isinstance(data, tuple) and len(data) == 2:
        data = dataset_from_arrays(*data)
    if not isinstance(data, Dataset):
        raise ConfigError("data must be a Dataset or a tuple (x, u) of arrays")
    bits = parse_bits(bits)
    spec = quantizer or QuantizerSpec()
    R = 1 if spec.dither == "none" else check_int("realizations", realizations, 1, 10000)
    prep = prepare(data, spec)
    A_ref, B_ref, ref = _reference(data, prep, system)
    seeds = np.random.SeedSequence(dither_seed).spawn(R)
    moms = [
        quantized_moments(prep, list(bits), spec, np.random.default_rng(s) if spec.dither != "none" else None)
        for s in seeds
    ]
    err, notes = _errors(bits, moms, A_ref, B_ref)
    overload = {b: float(np.mean([m[j].overload_fraction for m in moms])) for j, b in enumerate(bits)}
    theory = {
        b: theorem1_on_data(prep.exact.PP, prep.exact.T, A_ref, B_ref, moms[0][j].eps, spec.dither, overload[b])
        for j, b in enumerate(bits)
    }
    return RecordedResult(
        bits,
        ref,
        A_ref,
        B_ref,
        {b: moms[0][j].eps for j, b in enumerate(bits)},
        err,
        overload,
        data.trajectories,
        data.steps,
        sorted(notes),
        theory,
    )
