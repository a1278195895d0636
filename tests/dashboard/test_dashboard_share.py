"""Keep & share: settings file round trip, "as a command" round trip (settings -> command -> parse -> the same
SweepConfig), exports of the current curves and figures, ``qsid-dashboard --settings FILE``."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support import HANG_S, Tab

from app.cli import build_parser
from app.cli.runner import config, system_from_args
from app.dashboard import share
from app.dashboard.session import iter_frames
from app.frames import exports
from app.settings import files
from app.settings.config import sweep_config
from app.settings.values import InputError, Values, resolve_system

ROOT = Path(__file__).resolve().parents[2]
SMALL = dict(trajectories=10, steps=60, realizations=4, mpc_steps=15)

CASES = {
    "defaults": Values(),
    "boeing, fixed per channel, no guard, BCLS": Values(
        system="boeing747",
        range_mode="fixed",
        fixed_range="-20 20\n-20 20\n-5 5\n-3 3\n-1 1\n-1 1",
        guard=False,
        identification="BCLS",
        dither="none",
        data_seed=5,
        dither_seed=9,
        bits=7,
    ),
    "custom, weights, x0, rho": Values(
        system="custom",
        a_text="0.9 0.1\n0 0.8",
        b_text="0; 1",
        log_q=(0.5, -1.0),
        log_r=(0.3,),
        x0="1, -0.5",
        rho_auto=False,
        rho=2.5,
        theta=0.35,
        horizon=17,
        u_max=0.35,
        mpc_steps=40,
    ),
    "shared range, paper scale": Values(range_mode="shared", trajectories=200, steps=1000, realizations=50),
    "tracking with a state box": Values(system="boeing747", x_ref="0.1, 0, 0, 0", x_max="5", compare_bits="2, 8"),
    "one fixed pair": Values(range_mode="fixed", fixed_range="-2.5, 2.5", log_q=(0.0, 1.0, -2.0), log_r=(0.7, 0.7)),
    "terminal weight Q and box, verdict settings": Values(
        qf="Q", terminal_box="0.8, 2, 2", verify_steps=1500, target=0.9, cost_gap=0.02, log_q=(0.3, -1.0, 0.0)
    ),
    "terminal weight numbers": Values(system="boeing747", qf="5", terminal_box="3"),
    "tracking a sine": Values(system="boeing747", reference="sine:u:1:40"),
    "offset-free constant reference": Values(tracking="offset-free", x_ref="0.5, 0, 0"),
    "real loop": Values(
        disturbance=0.01, disturbance_kind="uniform", feedback_bits=6, feedback_noise=0.002, loop_seed=4
    ),
}


def _same_config(a, b) -> None:
    sa, sb = a.system, b.system
    for k in ("A", "B", "x0", "Q", "R"):
        assert np.array_equal(getattr(sa, k), getattr(sb, k)), k
    assert dataclasses.replace(a, system="x") == dataclasses.replace(b, system="x")


@pytest.mark.parametrize("name", sorted(CASES))
def test_settings_to_command_to_the_same_sweepconfig(name):
    v = CASES[name]
    system = resolve_system(v).system
    want = sweep_config(v, system)
    *lines, bits_line = exports.command_lines(v)
    assert len(lines) == (2 if v.identification == "LS + BCLS" else 1)
    argv = shlex.split(bits_line)
    assert argv[:2] == ["qsid", "bits"]
    args = build_parser().parse_args(argv[1:])
    _same_config(config(args, system_from_args(args), mpc=True), want)
    assert (args.target, args.cost_gap) == (v.target, v.cost_gap)
    for line, est in zip(lines, (("ls", "bcls") if len(lines) == 2 else (want.estimator,))):
        argv = shlex.split(line)
        assert argv[:2] == ["qsid", "sweep"]
        args = build_parser().parse_args(argv[1:])
        got = config(args, system_from_args(args), mpc=True)
        _same_config(got, dataclasses.replace(want, estimator=est))


def test_command_is_short_at_the_defaults_and_names_changes():
    assert exports.command_lines(Values(identification="LS")) == [
        "qsid sweep --realizations=20 --trajectories=50 --steps=200",
        "qsid bits --realizations=20 --trajectories=50 --steps=200 --mpc-steps=50",
    ]
    line = exports.command_lines(Values(identification="LS", target=0.9, cost_gap=0.05, verify_steps=100))[-1]
    assert "--verify-steps=100" in line and line.endswith("--mpc-steps=50 --target=0.9 --cost-gap=0.05")
    line = exports.command_lines(CASES["boeing, fixed per channel, no guard, BCLS"])[0]
    assert "--system=boeing747" in line and "--no-guard" in line and "--limits=-20.0,20.0;" in line


@pytest.mark.parametrize("name", sorted(CASES))
def test_settings_json_round_trip(name):
    v = CASES[name]
    text = files.settings_json(v)
    assert json.loads(text)["kind"] == files.SETTINGS_KIND
    assert files.values_from_json(text) == v
    assert files.values_from_json(text.encode()) == v


@pytest.mark.parametrize(
    "doc, needle",
    [
        ("{not json", "not a JSON file"),
        ('{"values": {}}', "not a qsid settings file"),
        ('{"kind": "qsid-dashboard-settings", "values": {"colour": 1}}', "unknown field(s) colour"),
        ('{"kind": "qsid-dashboard-settings", "values": {"bits": "four"}}', "bits: expected a whole number, got str"),
        (
            '{"kind": "qsid-dashboard-settings", "values": {"bits": 99}}',
            "bits: 99 is outside the slider's range 1 … 16",
        ),
        ('{"kind": "qsid-dashboard-settings", "values": {"realizations": 2.5}}', "whole number"),
        ('{"kind": "qsid-dashboard-settings", "values": {"guard": 1}}', "true or false"),
        ('{"kind": "qsid-dashboard-settings", "values": {"dither": "pink"}}', "dither: 'pink' is not one of"),
        ('{"kind": "qsid-dashboard-settings", "values": {"system": "custom", "a_text": "1 x"}}', "A row 1"),
        ('{"kind": "qsid-dashboard-settings", "values": {"log_q": [1e400]}}', "log_q: inf is not a finite number"),
        ("[" * 100000, "not a JSON file"),
    ],
)
def test_bad_settings_are_one_plain_line(doc, needle):
    with pytest.raises(InputError) as info:
        files.values_from_json(doc)
    msg = str(info.value)
    assert needle in msg and "\n" not in msg and len(msg) < 400, msg


@pytest.fixture(scope="module")
def frame():
    v = Values(**SMALL)
    *_, last = iter_frames(v)
    assert last.done == last.total
    return last


def test_export_curves_csv_and_json(frame):
    rows = list(csv.DictReader(io.StringIO(exports.curves_csv(frame))))
    assert len(rows) == 2 * 16 and {r["estimator"] for r in rows} == {"LS", "BCLS"}
    ls4 = next(r for r in rows if r["estimator"] == "LS" and r["bits"] == "4")
    assert float(ls4["err_A_mean"]) == pytest.approx(frame.rows["LS"][4]["err_A"]["mean"])
    a = frame.rows["LS"][4].get("assumptions")  # rows carry them once the dashboard computes them
    assert ls4["theorem1_holds"] == ("" if not a else str(a["theorem1_holds"]))
    r4 = frame.rows["LS"][4]
    assert float(ls4["stabilized_fraction"]) == pytest.approx(r4["stabilized_fraction"])
    assert int(ls4["converged"]) == r4["closed_loop_outcomes"]["converged"]
    assert float(ls4["steady_state_error_mean"]) == pytest.approx(r4["steady_state_error"]["mean"])

    def bad(c):
        raise AssertionError(c)

    d = json.loads(exports.curves_json(frame), parse_constant=bad)
    assert d["settings"] == json.loads(files.settings_json(frame.values))["values"]
    assert [r["bits"] for r in d["curves"]["BCLS"]] == list(range(1, 17)) and d["complete"] is True
    assert d["command"] == exports.command_lines(frame.values)


def test_export_figures_is_one_offline_page(frame):
    page = exports.frame_html(frame)
    assert page.startswith("<!DOCTYPE html>") and page.count('class="panel"') >= 3
    assert not re.search(r"<script[^>]*src=", page)  # plotly.js inlined: one file, works offline
    assert "Plotly.newPlot" in page and "qsid sweep" in page
    from app.figures import registry

    frame.datalength = None  # the data-length study was not run: its empty plot is left out of the page
    assert page.count('class="panel"') == exports.frame_html(frame).count('class="panel"') == len(registry.VIEWS) - 1


@pytest.mark.slow
def test_download_then_upload_gives_the_same_view(monkeypatch):
    from app.dashboard import DashboardApp

    app = DashboardApp(host="127.0.0.1", port=0, workers=0)
    try:
        one = Tab(app)
        one.set(system="boeing747")
        one.set(guard=False, dither_seed=3, horizon=12, x_ref="0.1, 0, 0, 0", **SMALL)
        one.session.views.compare_bits.value = "3, 5"
        one.session.controls.q_sliders[1].value = 1.5
        one.wait()
        sent = {}
        monkeypatch.setattr(
            one.session.client, "send_file_download", lambda name, content, **kw: sent.update({name: content})
        )
        ui = one.session.ui
        share._download(
            ui.share,
            None,
            ui._send_file,
            "qsid-settings.json",
            lambda _f: files.settings_json(ui.panel_values()),
            False,
        )
        assert set(sent) == {"qsid-settings.json"}
        two = Tab(app).wait()
        assert two.frame.values != one.frame.values
        share._uploaded(two.session.share, two.session.ui.receive, "qsid-settings.json", sent["qsid-settings.json"])
        two.wait()
        assert "Loaded settings" in two.session.share.status.content
        assert two.frame.values == one.frame.values and two.frame.values.log_q[1] == 1.5
        assert two.frame.values.compare_bits == "3, 5" and two.frame.values.x_ref == "0.1, 0, 0, 0"
        assert two.frame.rows == one.frame.rows and two.session.share.command.content.count("qsid sweep") == 2
        share._uploaded(
            two.session.share, two.session.ui.receive, "broken.json", b"{"
        )  # a bad file: a note, the view stays
        assert "Cannot load broken.json" in two.session.share.status.content and two.error is None
        for t in (one, two):
            t.close()
    finally:
        app.stop()


def test_dashboard_settings_flag(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"kind": "qsid-dashboard-settings", "values": {"bits": 99}}')
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run(
        [sys.executable, "-m", "app.dashboard", "--settings", str(bad), "--port", "0", "--workers", "0"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
        timeout=HANG_S,
    )
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("qsid-dashboard: error: bad.json: settings: bits"), r.stderr


def test_new_tabs_start_from_the_settings_file(tmp_path):
    from app.dashboard import DashboardApp

    v = Values(system="boeing747", bits=6, guard=False, **SMALL)
    f = tmp_path / "s.json"
    f.write_text(files.settings_json(v))
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, settings=files.load_settings_file(f))
    try:
        t = Tab(app).wait()
        assert t.frame.values.system == "boeing747" and t.frame.values.bits == 6 and t.frame.values.guard is False
        t.close()
    finally:
        app.stop()
