"""``qsid-dashboard --system FILE``: the plant files the CLI reads open in the dashboard
as the panel's custom system, with the CLI's numbers; a bad file is one line and exit status 2."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from support import HANG_S, SMALL, Tab

from app.cli import build_parser
from app.cli.runner import config, system_from_args
from app.settings import files
from app.settings.config import sweep_config
from app.settings.values import Values, resolve_system
from qsid_core import load_system

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "docs" / "data"


@pytest.mark.parametrize("name", ["servo", "pitch", "pendcart", "chain", "bus"])
def test_a_plant_file_is_the_same_plant_in_the_dashboard_and_the_cli(name):
    f = DATA / f"{name}.toml"
    v, notes = files.values_for_plant_file(f, Values())
    dash = sweep_config(v, resolve_system(v).system)
    args = build_parser().parse_args(["sweep", "--system", str(f)])
    cli = config(args, system_from_args(args), True)
    t = load_system(f)
    assert np.array_equal(dash.system.A, t.A) and np.array_equal(dash.system.B, t.B)
    assert np.array_equal(dash.system.A, cli.system.A) and np.array_equal(dash.system.B, cli.system.B)
    assert np.array_equal(np.asarray(dash.mpc.x0 or dash.system.x0), t.x0)
    if name == "bus":  # Q = diag(1e4, ...), R = 1e-6: beyond the sliders, and said so
        assert len(notes) == 2 and all("clipped" in n for n in notes)
    else:
        assert notes == []
        np.testing.assert_allclose(dash.mpc.resolve(dash.system).Q, np.diag(np.diag(t.Q)), rtol=0.03)


def test_the_dashboard_flag_refuses_a_bad_file_in_one_line(tmp_path):
    bad = tmp_path / "plant.toml"
    bad.write_text("A = [[1, 2]]\nB = [[1]]\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for target in (str(bad), str(tmp_path / "missing.toml")):
        r = subprocess.run(
            [sys.executable, "-m", "app.dashboard", "--system", target, "--port", "0", "--workers", "0"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            env=env,
            timeout=HANG_S,
        )
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        last = r.stderr.strip().splitlines()[-1]
        assert last.startswith(f"qsid-dashboard: error: --system {target}"), r.stderr


def test_new_tabs_open_on_the_plant_file():
    from app.dashboard import DashboardApp

    v, _ = files.values_for_plant_file(DATA / "pitch.toml", Values().replace(**SMALL))
    app = DashboardApp(host="127.0.0.1", port=0, workers=0, settings=v)
    try:
        t = Tab(app).wait()
        assert t.frame.values.system == "custom" and t.error is None
        np.testing.assert_array_equal(t.frame.system.A, load_system(DATA / "pitch.toml").A)
        assert t.frame.rows  # the tab computed on it
        t.close()
    finally:
        app.stop()
