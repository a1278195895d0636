"""The dashboard's what-if controls: dither kinds, input word length, sensor noise (and whether BCLS knows it)
reach the engine, the settings file and the "as a command" line alike; bad entries are one plain line."""

from __future__ import annotations

import dataclasses
import shlex

import numpy as np
import pytest

from app.cli import build_parser
from app.cli.runner import config, system_from_args
from app.dashboard.controls import CONTROLS
from app.frames import exports
from app.settings import files
from app.settings.config import sweep_config
from app.settings.values import InputError, Values, resolve_system
from qsid_core.quantization.quantize import DITHERS

WHAT_IF = Values(
    system="boeing747",
    dither="tpdf",
    input_bits="8, exact",
    state_bits="b, b, 12, exact",
    noise="0.01, 0, 0.02, 0",
    noise_known=True,
    identification="BCLS",
    range_mode="fixed",
    fixed_range="-20, 20",
)


def test_the_panel_has_every_what_if_control_and_dither_kind():
    names = {c.name: c for c in CONTROLS}
    assert {"input_bits", "state_bits", "noise", "noise_known"} <= set(names)
    assert names["dither"].choices == DITHERS == ("subtractive", "tpdf", "rpdf", "none")


def test_what_ifs_reach_the_engine_config():
    cfg = sweep_config(WHAT_IF, resolve_system(WHAT_IF).system)
    assert cfg.quantizer.dither == "tpdf" and cfg.input_bits == (8, "exact")
    assert cfg.state_bits == ("b", "b", 12, "exact")
    assert cfg.noise == (0.01, 0.0, 0.02, 0.0) and cfg.noise_known is True
    d = sweep_config(Values(), resolve_system(Values()).system)
    assert d.input_bits is None and d.noise == (0.0,) and d.noise_known is False  # the letter's setting


def test_what_ifs_survive_the_settings_file_and_the_command_line():
    assert files.values_from_json(files.settings_json(WHAT_IF)) == WHAT_IF
    system = resolve_system(WHAT_IF).system
    want = sweep_config(WHAT_IF, system)
    line, bits_line = exports.command_lines(WHAT_IF)  # the sweep, then 'qsid bits' with the same settings
    assert bits_line.startswith("qsid bits ")  # the same settings, and the loop length always written
    assert bits_line.split(" ", 2)[2] in (line.split(" ", 2)[2], line.split(" ", 2)[2] + " --mpc-steps=50")
    assert "--dither=tpdf" in line and "--input-bits=8,exact" in line and "--noise-known" in line
    assert "--state-bits=b,b,12,exact" in line
    args = build_parser().parse_args(shlex.split(line)[1:])
    got = config(args, system_from_args(args), mpc=True)
    for k in ("A", "B", "x0", "Q", "R"):
        assert np.array_equal(getattr(got.system, k), getattr(want.system, k))
    assert dataclasses.replace(got, system="x") == dataclasses.replace(want, system="x")


@pytest.mark.parametrize(
    "kw, needle",
    [
        (dict(input_bits="8, 9, 10"), "input_bits has 3 entries; the system has 2"),
        (dict(input_bits="lots"), "input bits must be"),
        (dict(state_bits="b, 3"), "state_bits has 2 entries; the system has 4"),
        (dict(state_bits="b, b, b, 40"), "state bits must be"),
        (dict(noise="0.1, 0.2"), "sensor noise: give one σ for every state or one per state"),
        (dict(noise="-0.1"), "noise must be in"),
    ],
)
def test_bad_what_if_entries_are_one_plain_line(kw, needle):
    v = Values(system="boeing747", **kw)
    with pytest.raises(InputError, match=needle):
        sweep_config(v, resolve_system(v).system)
