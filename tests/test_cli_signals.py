"""``qsid sweep`` with worker processes (``--workers``, ``--dask local``) stopped by a signal mid-run:
nothing it started survives, and ``--out`` is never left half-written (an existing file stays intact)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from support import HANG_S, descendants, gone_within  # noqa: E402

ENV = dict(os.environ, PYTHONPATH=str(ROOT))
LONG = ["sweep", "--bits", "2:16", "--realizations", "200", "--trajectories", "400", "--steps", "2000", "-q"]


def start(tmp_path, *extra, workers_expected=2, settle=3.0):
    out = tmp_path / "result.json"
    out.write_text("previous result\n")
    p = subprocess.Popen(
        [sys.executable, "-m", "app.cli", *LONG, "--out", str(out), *extra],
        cwd=ROOT,
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    end = time.monotonic() + HANG_S  # only a hang guard: a cold machine can take minutes to start a cluster
    desc: list[int] = []
    while time.monotonic() < end and p.poll() is None:  # workers up and computing
        desc = descendants(p.pid)
        if len(desc) >= workers_expected:
            time.sleep(settle)
            desc = descendants(p.pid)
            break
        time.sleep(0.2)
    return p, out, desc


def finish(p, desc):
    try:
        p.wait(timeout=60)
        err = p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(10)
    left = gone_within(desc, 60)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    return err, left


@pytest.mark.parametrize(
    "sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT, signal.SIGKILL], ids=["TERM", "HUP", "INT", "KILL"]
)
def test_sweep_workers_signal_leaves_nothing(tmp_path, sig):
    p, out, desc = start(tmp_path, "--workers", "2")
    assert p.poll() is None and len(desc) >= 2, desc
    p.send_signal(sig)
    err, left = finish(p, desc)
    assert left == [], f"still running after {sig.name}: {left}"
    assert out.read_text() == "previous result\n"  # the old file untouched, no partial one
    assert [f.name for f in tmp_path.iterdir()] == ["result.json"]  # no temporary file left either
    if sig != signal.SIGKILL:
        assert p.returncode == 130 and "interrupted" in err and "Traceback" not in err, (p.returncode, err)


@pytest.mark.xfail(
    reason="timing-dependent: on a cold or busy machine the local cluster's workers may not be up "
    "when the signal is sent (seen failing in a fresh-clone CI run); to be made deterministic",
    strict=False,
)
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["TERM", "INT"])
def test_sweep_dask_local_signal_leaves_nothing(tmp_path, sig):
    pytest.importorskip("distributed")
    p, out, desc = start(tmp_path, "--dask", "local:2", workers_expected=3, settle=20.0)  # past the cluster's start
    assert p.poll() is None and len(desc) >= 2, desc
    p.send_signal(sig)
    err, left = finish(p, desc)
    assert left == [], f"still running after {sig.name}: {left}"
    assert out.read_text() == "previous result\n"
    assert p.returncode == 130 and "Traceback" not in err, (p.returncode, err)


def test_out_is_written_whole_with_the_usual_permissions(tmp_path):
    out = tmp_path / "r.json"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "app.cli",
            "sweep",
            "--bits",
            "4",
            "--realizations",
            "2",
            "--trajectories",
            "5",
            "--steps",
            "50",
            "--no-mpc",
            "-q",
            "--out",
            str(out),
        ],
        cwd=ROOT,
        env=ENV,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    assert out.read_text().strip().startswith("{") and [f.name for f in tmp_path.iterdir()] == ["r.json"]
    mask = os.umask(0)
    os.umask(mask)
    assert os.stat(out).st_mode & 0o777 == 0o666 & ~mask
