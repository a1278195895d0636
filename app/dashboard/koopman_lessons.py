"""The nonlinear plants' lessons (rows of :data:`app.dashboard.lessons.LESSONS`): Koopman/EDMD from quantized data.

Each entry is ``(name, title, text, settings, plot)`` as :class:`~app.dashboard.lessons.Lesson` takes it. The
settings name every value whose default differs between linear and nonlinear plants (data size, MPC horizon
and length, training amplitude), so a lesson shows the same numbers whatever the panel held before. Every claim
is asserted at these settings by ``tests/dashboard/test_lessons_nonlinear.py``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["KOOPMAN_LESSONS"]

#: Van der Pol and the pendulum at a data size the dashboard draws in about half a minute.
_NONLINEAR: dict[str, Any] = dict(
    lifting="poly:3",
    identification="LS + BCLS",
    trajectories=400,
    steps=100,
    realizations=10,
    horizon=20,
    mpc_steps=200,
    state_amplitude=2.0,
    dither="subtractive",
    range_mode="per-channel",
    guard=True,
)

KOOPMAN_LESSONS: tuple[tuple[str, str, str, dict[str, Any], str], ...] = (
    (
        "koopman",
        "Koopman/EDMD from quantized data (Van der Pol)",
        "Van der Pol lifted by every monomial up to degree 3, 400 runs × 100 steps, 10 realizations; look at "
        "the error plot (show: Nonlinear). For b = 2..7 LS's error of [A_z, B_z] sits on its large-data limit "
        "(dashed, within 5 %): a quantization bias that more data do not remove, while BCLS, which de-biases "
        "every monomial exactly under subtractive dither, is 15 to 40 times lower for b = 3..6 (at the CLI's "
        "full scale, 2000 × 100, about 50 times at b = 3). From b = 11 on both agree within 10 %: the "
        "finite-data spread dominates. In 3-D: the plant's own flow (green, u = 0) from a grid of starts, each but "
        "the one at the origin winding onto the limit cycle, and the Koopman MPC loops at b = 3.",
        dict(system="van-der-pol", bits=3, **_NONLINEAR),
        "koopman-error",
    ),
    (
        "bias-variance",
        "Bias against variance: the pendulum at b = 2",
        "The pendulum at b = 2 (poly:3, 400 × 100, 10 realizations); look at the Koopman MPC outcomes "
        "(show: Nonlinear). BCLS's mean error of [A_z, B_z] is lower than LS's (below 1, LS above 1.4) but "
        "its spread is more than twice LS's: removing the bias of two-level data amplifies their noise. That "
        "variance costs control: LS's loops end within the convergence radius 0.1 in all 10 realizations, BCLS's "
        "in at most 8. None converges: each settles near, not at, the origin (bounded), as the unquantized EDMD's "
        "own loop does. Move b to 3: both end within the radius every time, and BCLS's error and prediction "
        "error are below LS's.",
        dict(system="pendulum", bits=2, **_NONLINEAR),
        "koopman-outcomes",
    ),
    (
        "bandwidth-koopman",
        "A link of limited bandwidth (Van der Pol)",
        "Van der Pol (poly:3, BCLS) over a link of 5·10⁵ bits: every sample of its 3 channels costs b bits, so b "
        "buys 5·10⁵ / (100 · 3 · b) runs of 100 steps (1666 at b = 1, 104 at b = 16). Look at the bandwidth "
        "plot (show: Nonlinear). Without sensor noise finer words always win: from b = 3 on the error of the lifted "
        "model falls about 2× per bit and the knee (dotted) is b = 16. The Koopman MPC loops (the share panel) "
        "converge at no b: each settles near the origin (bounded), as the unquantized model's own loop does; from "
        "b = 3 on every one ends within the convergence radius 0.1 (dotted), at b = 1 none.",
        dict(
            system="van-der-pol",
            bits=6,
            **{**_NONLINEAR, "identification": "BCLS", "trajectories": 100, "realizations": 5},
            total_bits=5e5,
        ),
        "koopman-bandwidth",
    ),
)
