"""Dictionaries of observables (liftings) for EDMD: monomials, radial basis functions, the identity.

A lifting maps a state ``x`` (n,) to ``z = psi(x)`` (L,); the state is read back by the rows of
``z`` that hold it, ``x = C z`` (:attr:`Lifting.C`). Specs (:func:`parse_lifting`):

``identity``
    ``z = x`` (L = n): EDMD is then exactly the letter's least squares.
``poly:d``
    every monomial ``x^alpha`` of total degree ``|alpha| = 0 .. d``, the constant and ``x`` itself
    first, then degree 2, 3, ... (graded, lexicographic within a degree); L = C(n + d, d).
``rbf:K`` (``rbf:K:thin-plate``, ``rbf:K:gauss``)
    ``z = [x, phi(|x - c_1|), .., phi(|x - c_K|)]`` with ``phi(r) = r^2 log r`` (thin-plate, default)
    or ``exp(-(r / s)^2)`` (Gaussian, ``s`` the mean spacing of the centres); the K centres are drawn
    U[-a, a]^n from ``numpy.random.default_rng(seed)`` (``a`` the plant's training amplitude). L = n + K.

Monomial liftings carry their exponents (:attr:`MonomialLifting.exponents`): that is what makes an
exact de-biasing of quantized data possible (:mod:`qsid_core.identification.edmd`); radial functions
have none.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from ..errors import ConfigError, short_repr

__all__ = [
    "LIFTINGS",
    "Lifting",
    "MAX_DEGREE",
    "MAX_FEATURES",
    "MonomialLifting",
    "RBFLifting",
    "bernoulli_shifted",
    "parse_lifting",
]

#: The lifting kinds (``poly:d``, ``rbf:K[:kind]``, ``identity``).
LIFTINGS = ("identity", "poly", "rbf")
#: Largest total degree of ``poly:d``.
MAX_DEGREE = 8
#: Largest number of features L.
MAX_FEATURES = 120
RBF_KINDS = ("thin-plate", "gauss")


@dataclass(frozen=True, eq=False)
class Lifting:
    """A dictionary of observables ``psi: R^n -> R^L`` with the state in rows :attr:`state_rows`.

    Attributes
    ----------
    spec : str
        The spec it was parsed from (``"poly:3"``).
    n : int
        Number of states.
    state_rows : tuple of int, length n
        Row of ``z`` holding ``x_i``.
    """

    spec: str
    n: int
    state_rows: tuple[int, ...]

    @property
    def L(self) -> int:
        """Number of features."""
        raise NotImplementedError

    @property
    def C(self) -> np.ndarray:
        """The read-back ``x = C z``, shape (n, L): ones at ``(i, state_rows[i])``."""
        C = np.zeros((self.n, self.L))
        C[np.arange(self.n), list(self.state_rows)] = 1.0
        return C

    def lift(self, x: np.ndarray) -> np.ndarray:
        """``psi(x)`` for a batch: x of shape (..., n) -> (..., L)."""
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class MonomialLifting(Lifting):
    """Monomials ``prod_c x_c^E[i, c]``.

    Attributes
    ----------
    exponents : ndarray of int64, shape (L, n)
    """

    exponents: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int64))

    @property
    def L(self) -> int:
        return int(self.exponents.shape[0])

    @property
    def degree(self) -> int:
        """Largest total degree."""
        return int(self.exponents.sum(axis=1).max())

    def lift(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        d = int(self.exponents.max())
        pw = np.empty(x.shape + (d + 1,))  # (..., n, d + 1): powers by repeated products (no pow calls)
        pw[..., 0] = 1.0
        for k in range(1, d + 1):
            pw[..., k] = pw[..., k - 1] * x
        out = np.ones(x.shape[:-1] + (self.L,))
        for c in range(self.n):
            out *= pw[..., c, :][..., self.exponents[:, c]]
        return out


@dataclass(frozen=True, eq=False)
class RBFLifting(Lifting):
    """``[x, phi(|x - c_k|)]`` for K centres.

    Attributes
    ----------
    centres : ndarray, shape (K, n)
    kind : {"thin-plate", "gauss"}
    width : float
        ``s`` of the Gaussian (unused for thin-plate).
    """

    centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    kind: str = "thin-plate"
    width: float = 1.0

    @property
    def L(self) -> int:
        return self.n + int(self.centres.shape[0])

    def lift(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        r2 = ((x[..., None, :] - self.centres) ** 2).sum(axis=-1)
        if self.kind == "gauss":
            phi = np.exp(-r2 / self.width**2)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                phi = np.where(r2 > 0, 0.5 * r2 * np.log(np.where(r2 > 0, r2, 1.0)), 0.0)  # r^2 log r
        return np.concatenate([x, phi], axis=-1)


def monomial_exponents(n: int, d: int) -> np.ndarray:
    """Every exponent vector of total degree 0..d, graded then lexicographic (descending), shape (L, n)."""
    rows: list[tuple[int, ...]] = []
    for deg in range(d + 1):
        rows += sorted((e for e in itertools.product(range(deg + 1), repeat=n) if sum(e) == deg), reverse=True)
    return np.array(rows, dtype=np.int64).reshape(-1, n)


def _field_error(spec: object, why: str) -> ConfigError:
    return ConfigError(f"lifting {short_repr(spec)}: {why}; use identity, poly:D (D >= 1) or rbf:K[:thin-plate|gauss]")


def parse_lifting(spec: str, n: int, amplitude: float = 2.0, seed: int = 0) -> Lifting:
    """The lifting named by ``spec`` for ``n`` states.

    Parameters
    ----------
    spec : str
        ``identity``, ``poly:d`` (1 <= d <= :data:`MAX_DEGREE`) or ``rbf:K[:thin-plate|gauss]`` (K >= 1).
    n : int
        Number of states.
    amplitude : float
        RBF centres are drawn U[-amplitude, amplitude]^n.
    seed : int
        Seed of the RBF centres.

    Raises
    ------
    ConfigError
        Unknown kind, degree 0, K < 1, or more than :data:`MAX_FEATURES` features.
    """
    if not isinstance(spec, str):
        raise _field_error(spec, "not a string")
    parts = spec.strip().lower().split(":")
    kind = parts[0]
    if kind == "identity" and len(parts) == 1:
        return MonomialLifting("identity", n, tuple(range(n)), np.eye(n, dtype=np.int64))
    if kind not in LIFTINGS or len(parts) < 2:
        raise _field_error(spec, "unknown dictionary")
    try:
        k = int(parts[1])
    except ValueError:
        raise _field_error(spec, f"{parts[1]!r} is not a whole number") from None
    if kind == "poly":
        if len(parts) != 2 or not 1 <= k <= MAX_DEGREE:
            raise _field_error(spec, f"the degree must be 1..{MAX_DEGREE} (degree 0 has no state to read back)")
        L = math.comb(n + k, k)
        if L > MAX_FEATURES:
            raise _field_error(spec, f"{L} features for {n} states exceed {MAX_FEATURES}")
        E = monomial_exponents(n, k)
        return MonomialLifting(f"poly:{k}", n, tuple(range(1, n + 1)), E)
    rbf_kind = parts[2] if len(parts) > 2 else "thin-plate"
    if len(parts) > 3 or rbf_kind not in RBF_KINDS:
        raise _field_error(spec, f"the radial function must be one of {', '.join(RBF_KINDS)}")
    if not 1 <= k <= MAX_FEATURES - n:
        raise _field_error(spec, f"K must be 1..{MAX_FEATURES - n} centres")
    centres = np.random.default_rng(seed).uniform(-amplitude, amplitude, size=(k, n))
    width = float(2.0 * amplitude / max(k, 1) ** (1.0 / n))
    return RBFLifting(f"rbf:{k}:{rbf_kind}", n, tuple(range(n)), centres, rbf_kind, width)


def _bernoulli_numbers(k: int) -> list[Fraction]:
    """``B_0 .. B_k`` (with ``B_1 = -1/2``)."""
    B = [Fraction(1)]
    for m in range(1, k + 1):
        B.append(-sum((Fraction(math.comb(m + 1, j)) * B[j] for j in range(m)), Fraction(0)) / (m + 1))
    return B


def bernoulli_shifted(kmax: int) -> np.ndarray:
    """Coefficients of ``B_k(y + 1/2)`` in powers of ``y``: ``out[k, i]``, shape (kmax + 1, kmax + 1).

    With subtractive dither ``x~ = x + e``, ``e ~ U[-eps/2, eps/2]``:
    ``E[sum_i out[k, i] x~^i eps^(k - i)] = E[eps^k B_k(x~/eps + 1/2)] = x^k`` (Bernoulli polynomials
    integrate to ``int_t^(t+1) B_k(s) ds = t^k``). Row 2 is ``y^2 - 1/12``: the letter's BCLS.
    """
    Bn = _bernoulli_numbers(kmax)
    half = [(Fraction(2) ** (1 - j) - 1) * Bn[j] for j in range(kmax + 1)]  # B_j(1/2)
    out = np.zeros((kmax + 1, kmax + 1))
    for k in range(kmax + 1):
        for i in range(k + 1):
            out[k, i] = float(math.comb(k, i) * half[k - i])
    return out
