"""The server compiles (or loads) the kernels before it prints its URL, and says what it is doing meanwhile:
which step ("kernel 3 of 7"), about how long the whole start takes, and a line every few seconds while a step
runs; the engine only reports through a callback."""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def start_and_stop(cache: str | None, *command: str) -> list[str]:
    """The lines ``qsid dashboard: ...`` a server prints up to its URL (``command``: how Python runs it; default
    ``-m app.dashboard --port 0 --workers 1``), then stopped by SIGTERM; ``cache``: numba's cache directory."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), **({"NUMBA_CACHE_DIR": cache} if cache else {}))
    p = subprocess.Popen(
        [sys.executable, *(command or ("-m", "app.dashboard", "--port", "0", "--workers", "1"))],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    lines = []
    try:
        assert p.stdout is not None
        for line in p.stdout:
            lines.append(line.strip())
            if line.startswith("qsid dashboard: http://"):
                break
        p.send_signal(signal.SIGTERM)
        p.wait(60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait(10)
    return [x for x in lines if x.startswith("qsid dashboard:")]


def _steps(lines: list[str]) -> list[tuple[int, int]]:
    """The ``kernel k of n`` steps announced, in order (the "still ..." repeats left out)."""
    out = []
    for ln in lines:
        m = re.match(r"qsid dashboard: kernel (\d+) of (\d+): \S", ln)
        if m:
            out.append((int(m.group(1)), int(m.group(2))))
    return out


def _says_progress_then_ready(lines: list[str]) -> None:
    from qsid_core import PRESETS
    from qsid_core.studies import kernel_steps

    n = 1 + len(kernel_steps([make() for make in PRESETS.values()]))
    assert _steps(lines) == [(k, n) for k in range(1, n + 1)], lines  # every step, in order, before the URL
    order = [
        "qsid dashboard: starting the server and 1 worker process",
        "qsid dashboard: kernel 1 of",
        "qsid dashboard: the worker process loads the kernels",
        "qsid dashboard: computing the first view",
        "qsid dashboard: http://",
    ]
    at = [next(i for i, ln in enumerate(lines) if ln.startswith(s)) for s in order]
    assert at == sorted(at) and at[-1] == len(lines) - 1, lines  # the ready line last, as before
    still = [ln for ln in lines if ln.startswith("qsid dashboard: still ")]
    assert all(re.search(r": \d+ s so far, \d+ s in all$", ln) for ln in still), still


@pytest.mark.slow  # starts real dashboard processes with an empty kernel cache
def test_a_cold_start_says_what_it_compiles_then_a_warm_start_what_it_loads(tmp_path):
    from app.dashboard.lifecycle import COLD_START, WARM_START, kernel_names

    first = start_and_stop(str(tmp_path))
    assert first[0] == f"qsid dashboard: {COLD_START}", first
    assert "2 to 3 minutes" in first[0]  # about how long, said before it starts
    _says_progress_then_ready(first)
    cached = {p.name.split("-")[0] for p in tmp_path.rglob("*.nbi")}
    assert cached == set(kernel_names())  # every kernel compiled before the URL
    second = start_and_stop(str(tmp_path))
    assert second[0] == f"qsid dashboard: {WARM_START}", second
    assert not any("compiling" in ln for ln in second)
    _says_progress_then_ready(second)


def test_a_step_that_takes_long_is_repeated_every_tick():
    from app.dashboard.lifecycle import StartupReport

    out = io.StringIO()
    release = threading.Event()
    with StartupReport(out, tick=0.05) as report:
        report.say("starting")
        report.step("kernel 1 of 2: the box QP")
        release.wait(0.6)  # a step of 0.6 s: about a dozen ticks
        report.step("kernel 2 of 2: the EDMD (Koopman) kernel")
    lines = out.getvalue().splitlines()
    assert lines[:2] == ["qsid dashboard: starting", "qsid dashboard: kernel 1 of 2: the box QP"]
    assert lines[-1] == "qsid dashboard: kernel 2 of 2: the EDMD (Koopman) kernel"
    still = lines[2:-1]
    assert still and all(
        re.fullmatch(r"qsid dashboard: still kernel 1 of 2: \d+ s so far, \d+ s in all", x) for x in still
    )
    assert len(still) >= 2  # repeated, not said once


@pytest.mark.slow  # compiles every kernel where the cache does not hold it yet
def test_the_engine_reports_each_warm_up_step_through_its_callback_and_prints_nothing(capsys):
    from qsid_core import PRESETS
    from qsid_core.studies import compile_kernels, kernel_steps

    presets = [make() for make in PRESETS.values()]
    seen: list = []
    compile_kernels(presets, lambda k, n, what: seen.append((k, n, what)))
    n = len(kernel_steps(presets))
    assert [(k, m) for k, m, _ in seen] == [(k, n) for k in range(1, n + 1)]
    assert seen[0][2] == "the box QP" and all(w for _, _, w in seen)
    assert capsys.readouterr() == ("", "")


@pytest.mark.slow  # starts a real dashboard process
def test_a_terminal_hears_at_once_that_the_command_started_and_a_pipe_does_not():
    import pty
    import select
    import time

    from app.dashboard import LOADING

    main, sub = pty.openpty()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    args = [sys.executable, "-m", "app.dashboard", "--port", "0", "--workers", "0"]
    p = subprocess.Popen(args, cwd=ROOT, env=env, stdin=subprocess.DEVNULL, stdout=sub, stderr=subprocess.DEVNULL)
    os.close(sub)
    text, t0 = b"", time.monotonic()
    try:
        while b"qsid dashboard: http://" not in text and time.monotonic() - t0 < 600:
            ready, _, _ = select.select([main], [], [], 1.0)
            if ready:
                try:
                    text += os.read(main, 4096)
                except OSError:  # the process ended
                    break
    finally:
        p.send_signal(signal.SIGTERM)
        try:
            p.wait(60)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait(10)
        os.close(main)
    lines = [ln.strip() for ln in text.decode("utf-8", "replace").splitlines() if ln.strip()]
    assert lines and lines[0] == LOADING, lines  # before anything else, on a terminal
    assert any(ln.startswith("qsid dashboard: http://") for ln in lines), lines
    piped = subprocess.run(
        [sys.executable, "-c", "import sys; sys.argv = ['qsid-dashboard']; import app.dashboard"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
    )
    assert piped.returncode == 0 and piped.stdout == "", piped.stdout  # a pipe gets only what it got before


#: Runs the dashboard with :func:`~app.dashboard.lifecycle.freeze_heap` reporting what it froze, and when.
_FREEZE_REPORTED = """
import gc, sys
import app.dashboard.server as server
freeze = server.freeze_heap
def reported():
    n = freeze()
    print(f"qsid dashboard: frozen {n} objects, {len(gc.get_objects())} left to the collector", flush=True)
    return n
server.freeze_heap = reported
sys.exit(server.main(["--port", "0", "--workers", "0"]))
"""


def test_the_server_freezes_what_its_start_made_after_the_first_view_before_its_url():
    lines = start_and_stop(None, "-c", _FREEZE_REPORTED)
    first = next(i for i, ln in enumerate(lines) if ln.startswith("qsid dashboard: computing the first view"))
    frozen = [i for i, ln in enumerate(lines) if ln.startswith("qsid dashboard: frozen ")]
    assert len(frozen) == 1 and first < frozen[0] == len(lines) - 2, lines  # once, after the view, before the URL
    m = re.match(r"qsid dashboard: frozen (\d+) objects, (\d+) left", lines[frozen[0]])
    assert m and int(m.group(1)) > 100_000 and int(m.group(2)) < int(m.group(1)) // 100, lines[frozen[0]]
