"""The hypotheses of Theorem 1 and of BCLS in plain words, from the engine's per-b ``assumptions`` rows.

The engine decides (:mod:`qsid_core.studies.assumptions`); this module only words its
flags for the plots' notes and the summary.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from qsid_core.studies import FIT_TOLERANCE

__all__ = ["flags", "theorem1_reasons", "bcls_reasons", "fits_reasons", "line_holds", "bits_text", "short", "CAPTION"]

#: What every view of the ultimate bound says about it.
CAPTION = "δ bounds ‖x_t‖ as t → ∞; assumes x_ref = 0"

#: Plain words for each failing hypothesis (key: the engine's flag).
_WHY = {
    "sensor_noise_known": "sensor noise not known to BCLS: it removes only the quantization noise's bias",
    "known_noise": "no dither of known variance (subtractive or tpdf): the quantization error's variance "
    "depends on the signal",
    "no_overload": "overload: the quantizer range clips samples, and the clipped samples move the estimate by "
    "more than a third of its finite-data fluctuation (guard band or a wider range fixes it)",
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
    drift = "wander, like the dc-motor's angle," if where == "on" else "grow"
    return (
        f"A has an eigenvalue {where} the unit circle{kind}: Ψ Ψᵀ/T does not converge, so Theorem 1's "
        f"T → ∞ statement does not apply (the states {drift} instead of settling: the data are not stationary); "
        "a stable plant shows it hold: boeing747 (the dashboard's theorem1 lesson)"
    )


#: Hypotheses judged per block: the row has ``<key>_A`` and ``<key>_B``.
_PER_BLOCK = ("no_overload", "large_data")
_HAT = {"A": "Â", "B": "B̂"}


def line_holds(row: Mapping, block: str | None = None) -> bool:
    """Theorem 1's line is drawn as applying for ``block`` ('A', 'B'; None: both): every hypothesis holds,
    or one formally fails yet the measured LS error is on the line (True where the row has no flags)."""
    a = flags(row)
    if a is None:
        return True
    blocks = (block,) if block else ("A", "B")
    return all(a.get(f"theorem1_holds_{k}", a.get("theorem1_holds", True)) or a.get(f"fits_{k}", False) for k in blocks)


def _engine_words(rows: Sequence[Mapping], key: str, bad: Sequence[int]) -> str:
    """The engine's own sentence for ``key`` at the largest failing b (it names the range and the share clipped)."""
    if key == "no_overload":
        a = flags(next(r for r in rows if r["bits"] == bad[-1])) or {}
        note = next((x for x in a.get("notes", ()) if x.startswith("overload:")), None)
        if note:
            return note
    if key == "stationary":
        return _stationary_words(flags(next(r for r in rows if r["bits"] == bad[0])) or {})
    return _WHY[key]


def _failing(rows: Sequence[Mapping], key: str, block: str | None) -> list:
    """The b where ``key`` fails (for ``block``) and the line is not kept by a fitting prediction."""
    out = []
    for r in rows:
        a = flags(r)
        if a is None:
            continue
        if block is None:
            if not a.get(key, True):
                out.append(r["bits"])
        elif not a.get(f"{key}_{block}", a.get(key, True)) and not a.get(f"fits_{block}", False):
            out.append(r["bits"])
    return out


def _reasons(rows: Sequence[Mapping], keys: Sequence[str], per_block: bool = False) -> list[str]:
    out = []
    n_rows = len([r for r in rows if flags(r) is not None])
    for key in keys:
        if per_block and key in _PER_BLOCK:
            bad_a, bad_b = _failing(rows, key, "A"), _failing(rows, key, "B")
            groups = [(bad_a, "")] if bad_a == bad_b else [(bad_a, "A"), (bad_b, "B")]
        else:
            groups = [(_failing(rows, key, None), "")]
        for bad, blk in groups:
            if not bad:
                continue
            words = _engine_words(rows, key, bad)
            where = [f"for {_HAT[blk]}"] if blk else []
            if len(bad) != n_rows:
                where.append(bits_text(bad))
            out.append(words + (f" ({', '.join(where)})" if where else ""))
    return out


def theorem1_reasons(rows: Sequence[Mapping]) -> list[str]:
    """Why Theorem 1's line does not apply, one sentence per failing hypothesis (with the block and b)."""
    return _reasons(rows, ("known_noise", "no_overload", "stationary", "large_data"), per_block=True)


def bcls_reasons(rows: Sequence[Mapping]) -> list[str]:
    """Why BCLS's known-noise model fails (dither, overload), with the b where it fails."""
    return _reasons(rows, ("known_noise", "no_overload", "sensor_noise_known"))


def fits_reasons(rows: Sequence[Mapping]) -> list[str]:
    """Where a hypothesis formally fails yet the measured LS error is on Theorem 1's line (per block)."""
    out = []
    for k in ("A", "B"):
        bad = [
            r["bits"]
            for r in rows
            if (a := flags(r)) is not None and a.get(f"fits_{k}") and not a.get(f"theorem1_holds_{k}", True)
        ]
        if bad:
            out.append(
                f"a hypothesis formally fails yet the prediction fits for {_HAT[k]}: its mean LS error is "
                f"within {100 * FIT_TOLERANCE:g} % of Theorem 1's line ({bits_text(bad)})"
            )
    return out


def short(reason: str) -> str:
    """A reason in a few words for a plot's note: the part before ':' and the word lengths it names
    ("finite data (b = 2–16)"); the full sentence goes to the summary and the note's hover text."""
    head = reason.split(";")[0] if reason.startswith("overload:") else reason.split(":")[0]
    group = reason[reason.rfind(" (") :] if reason.endswith(")") and " (" in reason else ""
    tail = group if ("b = " in group or group.startswith(" (for ")) else ""
    return head + tail
