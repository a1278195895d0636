"""Linear-algebra tests of closed-loop stability: spectral radii, convergence certificates, stability radii.

The MPC built on a model ``(A^, B^)`` is, while no constraint is active, the
affine feedback ``u = -K^ x + k`` with ``K^`` the first gain of its finite-horizon
Riccati recursion. On the true plant that law gives ``x+ = (A - B K^) x + B k``:

* :func:`spectral_radius` -- ``max |eig(A - B K^)|`` per model: below 1 the linear
  law is stable on the true plant, above 1 it cannot settle at its equilibrium;
* :func:`lyapunov_gains` -- with ``S`` the solution of ``M'SM - S = -I``, the
  ``S``-norm of ``x_t - x_inf`` never grows, so ``|F_i (x_t - x_inf)| <= g_i ||x_0 - x_inf||_S``
  for every future step: a state from which the unconstrained law stays
  feasible forever, and therefore converges (:func:`certify`);
* :func:`complex_stability_radius` -- the smallest unstructured complex
  perturbation ``E`` (spectral norm) that makes ``M + E`` unstable:
  ``min over |z| = 1 of sigma_min(zI - M)``. ``||E||_2`` below it certifies
  stability (small-gain theorem; Hinrichsen & Pritchard, *Mathematical Systems
  Theory I*, Springer 2005, Sec. 5.3);
* :func:`controllability_margin` -- the relative smallest singular value of the
  controllability matrix (Assumption 2 of the letter asks ``(A^, B^)`` controllable).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "spectral_radius",
    "lyapunov_batch",
    "lyapunov_gains",
    "certify",
    "certify_batch",
    "complex_stability_radius",
    "small_gain_margin",
    "small_gain_holds",
    "data_rate_bits",
    "controllability_margin",
    "UNIT_CIRCLE_ROUNDOFF",
]

#: ``|lambda| - 1`` at most this is round-off of an eigenvalue on the unit circle (:func:`data_rate_bits`).
UNIT_CIRCLE_ROUNDOFF = 1e-7


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


def complex_stability_radius(M: np.ndarray, grid: int = 180) -> float:
    """``min over |z| = 1 of sigma_min(zI - M)``: the complex stability radius of a stable ``M``.

    ``M + E`` is stable for every complex ``E`` with ``||E||_2`` below it (and some
    ``E`` of that norm makes it unstable). Computed on a grid of ``grid`` points of
    the unit circle, then refined around each dip of the grid that can hold the
    minimum by a bounded scalar minimisation; the result is exact to about 1e-10 relative for the small
    systems here (the default grid of 180 gives the same radii as 720 to 1e-16 on both presets' loops, in
    a quarter of the time: the refinement, not the grid, sets the accuracy). 0 when ``M`` is not stable.

    Parameters
    ----------
    M : ndarray, shape (n, n)
    grid : int

    Returns
    -------
    float
    """
    from scipy.optimize import minimize_scalar

    M = np.asarray(M, dtype=float)
    if not np.all(np.isfinite(M)) or spectral_radius(M) >= 1.0:
        return 0.0
    n = M.shape[0]
    eye = np.eye(n)

    def smin(theta: float) -> float:
        return float(np.linalg.svd(np.exp(1j * theta) * eye - M, compute_uv=False)[-1])

    # real M: sigma_min is symmetric in theta, so [0, pi] is enough; the dips sit near the eigenvalues' angles
    th = np.union1d(np.linspace(0.0, np.pi, grid + 1), np.abs(np.angle(np.linalg.eigvals(M))))
    vals = np.linalg.svd(np.exp(1j * th)[:, None, None] * eye - M, compute_uv=False)[:, -1]
    best = float(vals.min())
    # sigma_min(zI - M) is 1-Lipschitz along the circle: near a grid point it is at least its value less half the
    # spacing, so only the dips (local minima of the grid) within that slack of the best value can hold the minimum
    slack = np.pi / grid / 2
    # neighbours across the ends mirror (sigma_min is even in theta and 2 pi periodic)
    left, right = np.r_[vals[1], vals[:-1]], np.r_[vals[1:], vals[-2]]
    dips = np.flatnonzero((vals <= left) & (vals <= right))
    for k in dips[np.argsort(vals[dips])]:
        if vals[k] - slack >= best:
            break
        lo, hi = th[max(k - 1, 0)], th[min(k + 1, th.size - 1)]
        r = minimize_scalar(smin, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
        best = min(best, float(r.fun))
    return best


def small_gain_holds(
    A: np.ndarray, B: np.ndarray, A_hat: np.ndarray, B_hat: np.ndarray, K: np.ndarray, grid: int = 720
) -> np.ndarray:
    """Whether :func:`small_gain_margin`'s test certifies each loop of a batch, decided cheaply where it can be.

    ``sigma_min(zI - M)`` is 1-Lipschitz along the unit circle, so on a grid of
    spacing ``h`` its minimum ``g`` gives ``g - h/2 <= r_C <= g``: a perturbation
    below ``g - h/2`` is certified and one at least ``g`` is not, without refining.
    A coarse grid, then a fine one, settle almost every loop; the few left are
    refined exactly (:func:`complex_stability_radius`).

    Parameters
    ----------
    A : ndarray, shape (n, n); B : ndarray, shape (n, m)
        The true plant.
    A_hat : ndarray, shape (L, n, n); B_hat : ndarray, shape (L, n, m); K : ndarray, shape (L, m, n)
        Models and the gains designed on them.

    Returns
    -------
    ndarray of bool, shape (L,)
    """
    A_hat, B_hat, K = (np.asarray(v, dtype=float) for v in (A_hat, B_hat, K))
    L, n, _ = A_hat.shape
    out = np.zeros(L, dtype=bool)
    with np.errstate(all="ignore"):
        E = (np.asarray(A, float) - A_hat) - (np.asarray(B, float) - B_hat) @ K
        M = A_hat - B_hat @ K
    fin = np.all(np.isfinite(E.reshape(L, -1)), axis=1) & np.all(np.isfinite(M.reshape(L, -1)), axis=1)
    todo = np.flatnonzero(fin)
    if not todo.size:
        return out
    todo = todo[spectral_radius(M[todo]) < 1.0]
    pert = np.full(L, np.inf)
    if todo.size:
        pert[todo] = np.linalg.norm(E[todo], 2, axis=(1, 2))
    for pts in (48, 180, grid):
        if not todo.size:
            return out
        th = np.linspace(0.0, np.pi, pts + 1)
        Z = np.exp(1j * th)[None, :, None, None] * np.eye(n) - M[todo][:, None]
        g = np.linalg.svd(Z, compute_uv=False)[..., -1].min(axis=1)
        yes = pert[todo] < g - (th[1] - th[0]) / 2
        out[todo[yes]] = True
        todo = todo[~yes & (pert[todo] < g)]
    for i in todo:
        out[i] = pert[i] < complex_stability_radius(M[i], grid)
    return out


def small_gain_margin(
    A: np.ndarray, B: np.ndarray, A_hat: np.ndarray, B_hat: np.ndarray, K: np.ndarray
) -> tuple[float, float]:
    """The robust-stability test of the gain ``K`` designed on ``(A^, B^)`` and applied to ``(A, B)``.

    The true closed loop is ``A - B K = (A^ - B^ K) + (dA - dB K)`` with
    ``dA = A - A^``, ``dB = B - B^``. By the small-gain theorem it is stable when
    ``||dA - dB K||_2 < r_C(A^ - B^ K)``, the complex stability radius of the
    nominal loop (:func:`complex_stability_radius`). A sufficient condition only:
    it ignores the structure of the perturbation.

    Returns
    -------
    (perturbation, radius) : floats ``||dA - dB K||_2`` and ``r_C(A^ - B^ K)``;
        the loop is certified when ``perturbation < radius``.
    """
    E = (np.asarray(A, float) - A_hat) - (np.asarray(B, float) - B_hat) @ K
    pert = float(np.linalg.norm(E, 2)) if np.all(np.isfinite(E)) else float("inf")
    return pert, complex_stability_radius(A_hat - B_hat @ K)


def data_rate_bits(A: np.ndarray) -> float:
    """The data-rate theorem's floor: ``sum over |lambda_i| > 1 of log2 |lambda_i|`` bits per sample.

    Any feedback loop that measures the state through a digital channel must send
    more than this many bits per sample to stabilize the plant, whatever the
    controller (Tatikonda & Mitter, IEEE TAC 2004; Nair & Evans, SIAM J. Control
    Optim. 2004). 0 for a stable (or marginally stable) plant: an eigenvalue with
    ``|lambda| <= 1 +`` :data:`UNIT_CIRCLE_ROUNDOFF` counts as on the unit circle (round-off
    of an eigenvalue computed at ``|lambda| = 1``; a double one, as of an undamped mass, moves by
    about the square root of the machine epsilon, 1.5e-8).

    Parameters
    ----------
    A : ndarray, shape (n, n)
    """
    lam = np.abs(np.linalg.eigvals(np.asarray(A, dtype=float)))
    return float(np.sum(np.log2(lam[lam > 1.0 + UNIT_CIRCLE_ROUNDOFF])))


def controllability_margin(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``sigma_min / sigma_max`` of ``[B, AB, ..., A^{n-1}B]`` per model (0: uncontrollable, NaN: no model).

    Each block is scaled by ``max(1, ||A||_2)^-k`` so that fast modes do not
    drown the measure; the controllability matrix's rank is unchanged.

    Parameters
    ----------
    A : ndarray, shape (L, n, n); B : ndarray, shape (L, n, m)

    Returns
    -------
    ndarray, shape (L,)
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    L, n, m = B.shape
    out = np.full(L, np.nan)
    ok = np.all(np.isfinite(A.reshape(L, -1)), axis=1) & np.all(np.isfinite(B.reshape(L, -1)), axis=1)
    if not ok.any():
        return out
    Ao, Bo = A[ok], B[ok]
    scale = np.maximum(1.0, np.linalg.norm(Ao, 2, axis=(1, 2)))[:, None, None]
    blocks, blk = [], Bo
    for _ in range(n):
        blocks.append(blk)
        blk = (Ao @ blk) / scale
    C = np.concatenate(blocks, axis=2)
    s = np.linalg.svd(C, compute_uv=False)
    with np.errstate(invalid="ignore", divide="ignore"):
        out[ok] = np.where(s[:, 0] > 0, s[:, -1] / s[:, 0], 0.0)  # C is n x nm: s has n values
    return out
