"""Every file the CLI writes (``--csv``, ``--out``, the figures of ``reproduce``) is written whole or not at all:
a temporary file beside it, renamed over it when complete. A failed or interrupted write leaves the old file
as it was and no temporary file behind."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from support import HANG_S

from qsid_core.studies import COLUMNS, replace_atomically, write_csv

# slow: interrupts real qsid processes mid-write
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
SMALL_SWEEP = ["sweep", "--bits", "4", "--realizations", "2", "--trajectories", "5", "--steps", "50", "--no-mpc"]


def test_a_failed_csv_write_keeps_the_old_file_and_leaves_no_temporary_file(tmp_path, monkeypatch):
    import qsid_core.studies.outputs as records

    path = tmp_path / "rows.csv"
    path.write_text("old rows\n")

    def full_disk(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(records.os, "replace", full_disk)
    with pytest.raises(OSError, match="No space left"):
        write_csv([], path)
    assert path.read_text() == "old rows\n"
    assert [f.name for f in tmp_path.iterdir()] == ["rows.csv"]


def test_replace_keeps_the_permission_bits(tmp_path):
    path = tmp_path / "r.json"
    path.write_text("old\n")
    os.chmod(path, 0o640)
    replace_atomically(path, "new\n")
    assert path.read_text() == "new\n" and os.stat(path).st_mode & 0o777 == 0o640


#: The child: a real ``qsid sweep --csv`` whose CSV write stops halfway (half the text in the temporary file,
#: then "writing" on stdout) until the parent's SIGTERM arrives.
CHILD = textwrap.dedent(
    """
    import os, sys, time
    import qsid_core.studies.outputs as records
    real = os.fdopen

    class Halfway:
        def __init__(self, f):
            self.f = f
        def __enter__(self):
            return self
        def __exit__(self, *exc):
            return self.f.__exit__(*exc)
        def write(self, text):
            self.f.write(text[: len(text) // 2])
            self.f.flush()
            print("writing", flush=True)
            while True:
                time.sleep(0.05)

    records.os = type("os", (), dict(vars(os), fdopen=lambda *a, **k: Halfway(real(*a, **k))))
    from app.cli.main import main
    sys.exit(main(sys.argv[1:]))
    """
)


def test_a_csv_write_interrupted_midway_keeps_the_old_file_and_leaves_no_temporary_file(tmp_path):
    path = tmp_path / "rows.csv"
    path.write_text("old rows\n")
    p = subprocess.Popen(
        [sys.executable, "-c", CHILD, *SMALL_SWEEP, "-q", "--csv", str(path)],
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert p.stdout.readline().strip() == "writing", p.stderr.read() if p.poll() is not None else ""
        assert [f.name for f in tmp_path.iterdir() if f.name.endswith(".tmp")], "no temporary file while writing"
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=HANG_S)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(10)
    assert p.returncode == 130 and "interrupted" in err and "Traceback" not in err, (p.returncode, err)
    assert path.read_text() == "old rows\n"
    assert [f.name for f in tmp_path.iterdir()] == ["rows.csv"]


def test_csv_and_out_written_whole(tmp_path):
    csv_path, out = tmp_path / "rows.csv", tmp_path / "r.json"
    r = subprocess.run(
        [sys.executable, "-m", "app.cli", *SMALL_SWEEP, "-q", "--csv", str(csv_path), "--out", str(out)],
        cwd=ROOT,
        env=dict(os.environ, PYTHONPATH=str(ROOT)),
        capture_output=True,
        text=True,
        timeout=HANG_S,
    )
    assert r.returncode == 0, r.stderr
    assert csv_path.read_text().splitlines()[0] == ",".join(COLUMNS)
    assert len(csv_path.read_text().splitlines()) > 1 and out.read_text().startswith("{")
    assert sorted(f.name for f in tmp_path.iterdir()) == ["r.json", "rows.csv"]


def test_a_stop_whose_interrupt_was_swallowed_still_ends_the_run_before_the_output(tmp_path):
    """A stop signal's KeyboardInterrupt can be lost (raised inside a finalizer, or caught by a library);
    the remembered stop ends the run at the next progress report and never lets the output be written."""
    import threading

    from app.cli.files import write_text
    from app.cli.runner import Reporter
    from app.stop import STOPPED

    out = tmp_path / "r.json"
    out.write_text("previous result\n")
    rep = Reporter(False)
    STOPPED.set()
    try:
        with pytest.raises(KeyboardInterrupt):
            write_text(out, "new result\n")
        with pytest.raises(KeyboardInterrupt):
            rep(1, 2, "simulate data")
        seen = []  # another thread's report (a pool's callback) is not where the run stops
        t = threading.Thread(target=lambda: seen.append(rep(1, 2, "simulate data") is None))
        t.start()
        t.join()
        assert seen == [True]
    finally:
        STOPPED.clear()
    assert out.read_text() == "previous result\n" and [p.name for p in tmp_path.iterdir()] == ["r.json"]
    write_text(out, "new result\n")
    rep(2, 2, "simulate data")
    assert out.read_text() == "new result\n"
