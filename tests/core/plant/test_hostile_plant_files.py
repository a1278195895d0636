"""Every way a plant file can be hostile gets one SystemDefinitionError line, the same from every public reader
(``load_system``, ``get_system``, ``is_nonlinear_file``, ``is_nonlinear``, ``load_nonlinear``): never a
RecursionError or OSError traceback, and a FIFO never blocks (the CLI and the dashboard:
``tests/cli/test_cli_hostile_systems.py``)."""

from __future__ import annotations

import threading

import pytest
from support import HANG_S, HOSTILE_PLANT_FILES, hostile_plant_file

from qsid_core import SystemDefinitionError, get_system, load_system
from qsid_core.plant import is_nonlinear, is_nonlinear_file, load_nonlinear

READERS = {
    "load_system": load_system,
    "get_system": get_system,
    "is_nonlinear_file": is_nonlinear_file,
    "is_nonlinear": is_nonlinear,
    "load_nonlinear": load_nonlinear,
}


def _refusal(fn, arg) -> str:
    """The message of the SystemDefinitionError ``fn(arg)`` raises, run in a thread (a hang guard: a FIFO opened
    for a blocking read would wait for ever)."""
    out: list = []

    def call():
        try:
            fn(arg)
            out.append(None)
        except BaseException as exc:  # noqa: BLE001 -- reported below, whatever it is
            out.append(exc)

    t = threading.Thread(target=call, daemon=True)
    t.start()
    t.join(HANG_S)
    assert out, f"{fn.__name__}({arg}) still running after {HANG_S} s: blocked?"
    exc = out[0]
    assert isinstance(exc, SystemDefinitionError), f"{fn.__name__}: {type(exc).__name__}: {exc}"
    assert "\n" not in str(exc)
    return str(exc)


@pytest.mark.parametrize("case", HOSTILE_PLANT_FILES)
def test_every_public_reader_refuses_a_hostile_file_with_one_line(tmp_path, case):
    path, words = hostile_plant_file(tmp_path, case)
    said = {name: _refusal(fn, str(path)) for name, fn in READERS.items() if case != "huge-float.json" or "sys" in name}
    assert all(words in text for text in said.values()), said
    if case not in ("huge-float.json", "list.json"):  # the file itself is unreadable: one line, whoever reads it
        assert len(set(said.values())) == 1, said


def test_a_missing_file_or_another_name_is_simply_not_nonlinear(tmp_path):
    assert not is_nonlinear_file(tmp_path / "none.json") and not is_nonlinear_file(tmp_path / "no" / "x.toml")
    assert not is_nonlinear_file(tmp_path) and not is_nonlinear("dc-motor") and is_nonlinear("van-der-pol")
    assert not is_nonlinear_file(3)  # type: ignore[arg-type]
