"""Linear-algebra tests of closed-loop stability: spectral radii and convergence certificates.

The MPC built on a model ``(A^, B^)`` is, while no constraint is active, the
affine feedback ``u = -K^ x + k`` with ``K^`` the first gain of its finite-horizon
Riccati recursion. On the true plant that law gives ``x+ = (A - B K^) x + B k``:

* :func:`spectral_radius` -- ``max |eig(A - B K^)|`` per model: below 1 the linear
  law is stable on the true plant, above 1 it cannot settle at its equilibrium;
* :func:`lyapunov_gains` -- with ``S`` the solution of ``M'SM - S = -I``, the
  ``S``-norm of ``x_t - x_inf`` never grows, so ``|F_i (x_t - x_inf)| <= g_i ||x_0 - x_inf||_S``
  for every future step: a state from which the unconstrained law stays
  feasible forever, and therefore converges (:func:`certify`).

Stability radii and the small-gain test are in :mod:`qsid_core.control.stability_radius`,
controllability and the data-rate floor in :mod:`qsid_core.control.controllability`.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "spectral_radius",
    "lyapunov_batch",
    "lyapunov_gains",
    "certify",
    "certify_batch",
]


def spectral_radius(M: np.ndarray) -> np.ndarray:
    """``max |eig(M_l)|`` for a batch of square matrices.

    Parameters
    ----------
    M : ndarray, shape (L, n, n) or (n, n)

    Returns
    -------
    ndarray, shape (L,) (or a 0-d array): NaN where ``M_l`` is not finite.
    """
    M = np.asarray(M, dtype=float)
    single = M.ndim == 2
    Mb = M[None] if single else M
    out = np.full(Mb.shape[0], np.nan)
    ok = np.all(np.isfinite(Mb.reshape(Mb.shape[0], -1)), axis=1)
    if ok.any():
        out[ok] = np.abs(np.linalg.eigvals(Mb[ok])).max(axis=1)
    return out[0] if single else out


def lyapunov_batch(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``S_l`` with ``M_l'S_l M_l - S_l = -I`` for a batch, and whether each is a valid certificate.

    Small ``n`` (<= 12) solves the ``n^2`` Kronecker systems in one batch; larger
    ones go through :func:`scipy.linalg.solve_discrete_lyapunov` one by one.

    Parameters
    ----------
    M : ndarray, shape (L, n, n)

    Returns
    -------
    (S, ok) : ndarray shape (L, n, n) (NaN where not ok) and bool ndarray shape (L,):
        ``ok`` where ``S`` is finite and positive definite (iff ``M`` is stable).
    """
    M = np.asarray(M, dtype=float)
    L, n, _ = M.shape
    S = np.full((L, n, n), np.nan)
    fin = np.all(np.isfinite(M.reshape(L, -1)), axis=1)
    if n <= 12 and fin.any():
        Mf = M[fin]
        # vec(M'SM) = (M' kron M') vec(S) for row-major vec
        Kr = np.einsum("lai,lbj->labij", np.swapaxes(Mf, 1, 2), np.swapaxes(Mf, 1, 2)).reshape(-1, n * n, n * n)
        lhs = np.eye(n * n) - Kr
        rhs = np.broadcast_to(np.eye(n).reshape(n * n), (len(Mf), n * n))
        with np.errstate(all="ignore"):
            try:
                sol = np.linalg.solve(lhs, rhs[..., None])[..., 0]
                S[fin] = sol.reshape(-1, n, n)
            except np.linalg.LinAlgError:
                for i in np.flatnonzero(fin):
                    d = _dlyap(M[i])
                    if d is not None:
                        S[i] = d
    else:
        for i in np.flatnonzero(fin):
            d = _dlyap(M[i])
            if d is not None:
                S[i] = d
    S = (S + np.swapaxes(S, 1, 2)) / 2
    ok = np.all(np.isfinite(S.reshape(L, -1)), axis=1)
    if ok.any():
        ok[ok] = np.linalg.eigvalsh(S[ok]).min(axis=1) > 0
    S[~ok] = np.nan
    return S, ok


def _dlyap(M: np.ndarray) -> np.ndarray | None:
    """``S`` with ``M'SM - S = -I`` (None if it is not finite and positive definite)."""
    from scipy.linalg import solve_discrete_lyapunov

    try:
        S = solve_discrete_lyapunov(M.T, np.eye(M.shape[0]))
    except (np.linalg.LinAlgError, ValueError):
        return None
    S = (S + S.T) / 2
    if not np.all(np.isfinite(S)):
        return None
    w = np.linalg.eigvalsh(S)
    return S if w.min() > 0 else None


def lyapunov_gains(M: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Lyapunov matrix of a stable ``M`` and the worst future size of each row of ``F e``.

    With ``S`` solving ``M'SM - S = -I`` (``S > 0`` iff the spectral radius of
    ``M`` is below 1), ``e_{t+1} = M e_t`` gives ``e_{t+1}'S e_{t+1} = e_t'S e_t - |e_t|^2``,
    so ``||e_t||_S`` never grows and, for every ``t >= 0``,
    ``|F_i e_t| <= ||S^{-1/2} F_i'||_2 ||e_0||_S``.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Closed-loop matrix with spectral radius < 1.
    F : ndarray, shape (rows, n)

    Returns
    -------
    (S, g) : ndarray shape (n, n) and ndarray shape (rows,) with ``g_i = sqrt(F_i S^-1 F_i')``,
        or None if ``M`` is not stable (or ``S`` is numerically not positive definite).
    """
    S = _dlyap(np.asarray(M, dtype=float))
    if S is None:
        return None
    try:
        Si = np.linalg.inv(S)
    except np.linalg.LinAlgError:
        return None
    g = np.sqrt(np.maximum(np.einsum("ri,ij,rj->r", F, Si, F), 0.0))
    return S, g


def certify_batch(
    M: np.ndarray,
    c: np.ndarray,
    F: np.ndarray,
    f: np.ndarray,
    bound: np.ndarray,
    x: np.ndarray,
    S: np.ndarray | None = None,
    margin: float = 1e-9,
) -> np.ndarray:
    """:func:`certify` for a batch of loops (``S`` from :func:`lyapunov_batch` if already known).

    Parameters
    ----------
    M : ndarray, shape (L, n, n); c : ndarray, shape (L, n)
    F : ndarray, shape (L, rows, n); f : ndarray, shape (L, rows); bound : ndarray, shape (rows,)
    x : ndarray, shape (L, n)
    S : ndarray, shape (L, n, n), optional

    Returns
    -------
    ndarray of bool, shape (L,)
    """
    L, n, _ = M.shape
    if S is None:
        S, ok = lyapunov_batch(M)
    else:
        ok = np.all(np.isfinite(S.reshape(L, -1)), axis=1)
    res = np.zeros(L, dtype=bool)
    if not ok.any():
        return res
    with np.errstate(all="ignore"):
        try:
            x_inf = np.linalg.solve(np.eye(n) - M[ok], c[ok][..., None])[..., 0]
            Si = np.linalg.inv(S[ok])
        except np.linalg.LinAlgError:
            return np.array([certify(M[i], c[i], F[i], f[i], bound, x[i], margin)[0] for i in range(L)])
        g = np.sqrt(np.maximum(np.einsum("lri,lij,lrj->lr", F[ok], Si, F[ok]), 0.0))
        e = x[ok] - x_inf
        size = np.sqrt(np.maximum(np.einsum("li,lij,lj->l", e, S[ok], e), 0.0))
        worst = np.abs(np.einsum("lri,li->lr", F[ok], x_inf) + f[ok]) + g * size[:, None]
        good = np.all(worst <= bound * (1 - margin), axis=1) & np.all(np.isfinite(x_inf), axis=1)
    res[ok] = good
    return res


def certify(
    M: np.ndarray, c: np.ndarray, F: np.ndarray, f: np.ndarray, bound: np.ndarray, x: np.ndarray, margin: float = 1e-9
) -> tuple[bool, np.ndarray | None]:
    """Whether the affine loop ``x+ = M x + c`` from ``x`` keeps ``|F x_t + f| <= bound`` forever.

    If it does, the loop never leaves the law ``x+ = M x + c`` and converges to
    its equilibrium ``x_inf = (I - M)^-1 c``. Sufficient test (see
    :func:`lyapunov_gains`): ``|F_i x_inf + f_i| + g_i ||x - x_inf||_S <= (1 - margin) bound_i``
    for every row ``i``.

    Parameters
    ----------
    M : ndarray, shape (n, n); c : ndarray, shape (n,)
    F : ndarray, shape (rows, n); f, bound : ndarray, shape (rows,)
    x : ndarray, shape (n,)
        The current state.
    margin : float
        Relative slack against rounding.

    Returns
    -------
    (certified, x_inf) : bool and the equilibrium (None where ``M`` is not stable).
    """
    lg = lyapunov_gains(M, F)
    if lg is None:
        return False, None
    S, g = lg
    n = M.shape[0]
    try:
        x_inf = np.linalg.solve(np.eye(n) - M, c)
    except np.linalg.LinAlgError:
        return False, None
    e = x - x_inf
    size = float(np.sqrt(max(e @ S @ e, 0.0)))
    with np.errstate(invalid="ignore"):
        worst = np.abs(F @ x_inf + f) + g * size
    ok = bool(np.all(worst <= bound * (1 - margin)) and np.all(np.isfinite(x_inf)))
    return ok, x_inf
