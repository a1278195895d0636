"""The hypotheses of Theorem 1 and of BCLS in plain words, from the engine's per-b ``assumptions`` rows.

The engine decides (:mod:`qsid_core.assumptions`); this module only words its
flags for the plots' notes and the summary.
"""

from __future__ import annotations

from typing import Mapping, Sequence

__all__ = ["flags", "theorem1_reasons", "bcls_reasons", "bits_text", "short", "CAPTION"]

#: What every view of the ultimate bound says about it.
CAPTION = "δ bounds ‖x_t‖ as t → ∞; assumes x_ref = 0"

#: Plain words for each failing hypothesis (key: the engine's flag).
_WHY = {
    "sensor_noise_known": "sensor noise not known to BCLS: it removes only the quantization noise's bias",
    "known_noise": "no dither of known variance (subtractive or tpdf): the quantization error's variance "
                   "depends on the signal",
    "no_overload": "overload: x + w leaves the quantizer range, so the error exceeds ε/2 and depends on the "
                   "signal (guard band or a wider range fixes it)",
    "large_data": "finite data: at this data size the predicted O(ε) fluctuation exceeds Theorem 1's O(ε²) "
                  "bias, so the error is expected above the line (a prediction: compare the points with it)",
}


def flags(row: Mapping) -> Mapping | None:
    """The engine's assumptions of one summary row (None if the row has none)."""
    a = row.get("assumptions")
    return a if isinstance(a, Mapping) else None


def bits_text(bits: Sequence[int]) -> str:
    """[1, 2, 3, 7] -> 'b = 1–3, 7'."""
    bits = sorted(bits)
    parts, i = [], 0
    while i < len(bits):
        j = i
        while j + 1 < len(bits) and bits[j + 1] == bits[j] + 1:
            j += 1
        parts.append(str(bits[i]) if i == j else f"{bits[i]}–{bits[j]}")
        i = j + 1
    return "b = " + ", ".join(parts)


def _stationary_words(a: Mapping) -> str:
    r = a.get("spectral_radius")
    where = "on" if r is not None and abs(r - 1.0) < 1e-6 else "on or outside"
    kind = " (integrator)" if where == "on" else ""
    return (f"A has an eigenvalue {where} the unit circle{kind}: Ψ Ψᵀ/T does not converge, so Theorem 1's "
            "T → ∞ statement does not apply")


def _reasons(rows: Sequence[Mapping], keys: Sequence[str]) -> list[str]:
    out = []
    for key in keys:
        bad = [r["bits"] for r in rows if flags(r) is not None and not flags(r).get(key, True)]
        if not bad:
            continue
        words = _stationary_words(flags(next(r for r in rows if r["bits"] == bad[0]))) \
            if key == "stationary" else _WHY[key]
        every = len(bad) == len([r for r in rows if flags(r) is not None])
        out.append(words + ("" if every else f" ({bits_text(bad)})"))
    return out


def theorem1_reasons(rows: Sequence[Mapping]) -> list[str]:
    """Why Theorem 1's line does not apply, one sentence per failing hypothesis (with the b where it fails)."""
    return _reasons(rows, ("known_noise", "no_overload", "stationary", "large_data"))


def bcls_reasons(rows: Sequence[Mapping]) -> list[str]:
    """Why BCLS's known-noise model fails (dither, overload), with the b where it fails."""
    return _reasons(rows, ("known_noise", "no_overload", "sensor_noise_known"))


def short(reason: str) -> str:
    """A reason in a few words for a plot's note: the part before ':' and the word lengths it names
    ("finite data (b = 2–16)"); the full sentence goes to the summary and the note's hover text."""
    head = reason.split(":")[0]
    tail = reason[reason.rfind(" (b = "):] if reason.endswith(")") and " (b = " in reason else ""
    return head + tail
