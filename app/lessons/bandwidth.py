"""The bandwidth lessons: a sensor link of limited bandwidth, where every sample of every channel costs b bits, so a
fixed budget of bits buys fewer runs at finer words. Two rows of :data:`app.lessons.table.LESSONS`
(``(name, title, text, settings, plot)``, as :class:`~app.lessons.table.Lesson` takes them): the Boeing 747 with and
without sensor noise, and Van der Pol lifted by Koopman/EDMD. Every number in their texts is asserted at these
settings by ``tests/dashboard/test_lesson_bandwidth.py``.
"""

from __future__ import annotations

from typing import Any

__all__ = ["bandwidth_lessons"]

Row = tuple[str, str, str, dict[str, Any], str]


def bandwidth_lessons(nonlinear: dict[str, Any]) -> tuple[Row, ...]:
    """The two lessons' rows; ``nonlinear``: the nonlinear lessons' common settings (data size, dictionary, MPC)."""
    return (
        (
            "bandwidth",
            "A link of limited bandwidth (Boeing 747)",
            "A sensor link carries 2·10⁶ bits; every sample of the Boeing's 6 channels costs b bits, so b buys "
            "2·10⁶ / (100 · 6 · b) runs of 100 steps (3333 at b = 1, 208 at b = 16). Look at the bandwidth plot "
            "(show: Bandwidth): noise-free on the left, with sensor noise on the right (on a phone and in presenter "
            "mode, noise-free on top, with sensor noise below). Noise-free (black), finer words always win: the error falls about 2× per bit and the knee (dotted) is b = 16, the top of the "
            "range. With sensor noise σ = 0.1 known to BCLS (orange) the error stops falling near b = 6, once the "
            "widest channels' quantization error ε/√12 is down to the noise's size (within 3×): that is its knee, "
            "the dashed prediction finds it too, and beyond it finer words only cost runs. Every loop stabilizes the "
            "true plant at every b (the share panels): here the word length decides the model, not the loop.",
            dict(
                system="boeing747",
                bits=6,
                identification="BCLS",
                noise="0.1",
                noise_known=True,
                total_bits=2e6,
                steps=100,
                realizations=10,
                dither="subtractive",
                range_mode="per-channel",
                guard=True,
            ),
            "bandwidth",
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
                **{**nonlinear, "identification": "BCLS", "trajectories": 100, "realizations": 5},
                total_bits=5e5,
            ),
            "koopman-bandwidth",
        ),
    )
