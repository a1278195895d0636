"""Sweeps on a real dask.distributed cluster (app/distributed.py).

The cluster tests start ``dask scheduler`` and ``dask worker`` as separate
processes on 127.0.0.1 (random ports, no dashboards, one thread per worker),
run tiny sweeps through :func:`app.distributed.make_executor` and compare the
JSON with the in-process run (timings excluded). They skip only when the
``distributed`` package is missing; with ``QSID_REQUIRE_DISTRIBUTED=1`` (set by
.ci/run) a missing package fails instead.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from app.distributed import ClusterError, DaskExecutor, make_executor, parse_dask_spec
from qsid_core import SweepConfig, run_sweep
from qsid_core.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
STARTUP_S = 60.0

TINY = dict(bits=(2, 5, 9), realizations=8, trajectories=12, steps=150)


def _need_distributed():
    if os.environ.get("QSID_REQUIRE_DISTRIBUTED") == "1":
        import distributed  # noqa: F401 -- CI: must run, a missing package fails
    else:
        pytest.importorskip("distributed")


def _json(res) -> str:
    d = res.to_dict()
    d.pop("timing_s")
    return json.dumps(d, sort_keys=True)


def _kill(proc: subprocess.Popen) -> None:
    """Stop a process started in its own session, with its children (the nanny's worker)."""
    if proc.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)


@contextlib.contextmanager
def dask_cluster(tmp: Path, workers: int = 2):
    """A scheduler and ``workers`` worker processes on 127.0.0.1; yields (address, workers, scheduler)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    procs: list[subprocess.Popen] = []

    def start(args, log):
        fh = open(tmp / log, "wb")
        p = subprocess.Popen([sys.executable, "-m", "dask", *args], cwd=ROOT, env=env, stdout=fh,
                             stderr=subprocess.STDOUT, start_new_session=True)
        fh.close()
        procs.append(p)
        return p

    try:
        sfile = tmp / "scheduler.json"
        sched = start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                       "--scheduler-file", str(sfile)], "scheduler.log")
        end = time.monotonic() + STARTUP_S
        while not sfile.exists() or not sfile.read_text().strip():
            assert sched.poll() is None, (tmp / "scheduler.log").read_text()
            assert time.monotonic() < end, "dask scheduler did not start in time"
            time.sleep(0.1)
        time.sleep(0.1)
        address = json.loads(sfile.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        wprocs = [start(["worker", address, "--nthreads", "1", "--nworkers", "1", "--host", "127.0.0.1",
                         "--no-dashboard", "--name", f"w{i}", "--local-directory", str(tmp / f"w{i}")],
                        f"worker{i}.log") for i in range(workers)]
        from distributed import Client

        with Client(address, timeout=10, set_as_default=False) as c:
            c.wait_for_workers(workers, timeout=STARTUP_S)
        yield address, wprocs, sched
    finally:
        for p in reversed(procs):
            _kill(p)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    _need_distributed()
    with dask_cluster(tmp_path_factory.mktemp("dask")) as (address, _, _):
        yield address


@pytest.fixture(scope="module")
def reference():
    return _json(run_sweep(SweepConfig(**TINY)))


# ----- parsing (no dask needed) -------------------------------------------------------------
@pytest.mark.parametrize("spec, workers, address", [
    ("local:3", 3, None), ("tcp://127.0.0.1:8786", None, "tcp://127.0.0.1:8786"),
    (" tcp://node-7.cluster:9000 ", None, "tcp://node-7.cluster:9000"),
])
def test_parse_dask_spec(spec, workers, address):
    p = parse_dask_spec(spec)
    assert (p.workers, p.address) == (workers, address)


def test_parse_local_uses_the_cores():
    assert parse_dask_spec("local").workers >= 1


@pytest.mark.parametrize("spec, match", [
    ("local:0", "between 1 and"), ("local:x", "integer"), ("udp://1.2.3.4:5", "cannot read"),
    ("tcp://127.0.0.1", "cannot read"), ("tcp://127.0.0.1:70000", "port"), ("", "cannot read"),
])
def test_parse_dask_spec_rejects(spec, match):
    with pytest.raises(ConfigError, match=match) as ei:
        parse_dask_spec(spec)
    assert "\n" not in str(ei.value)


# ----- real clusters ------------------------------------------------------------------------
@pytest.mark.cluster
def test_sweep_on_scheduler_and_two_worker_processes(cluster, reference):
    calls, notes = [], []
    with make_executor(cluster, notes.append) as ex:
        assert isinstance(ex, DaskExecutor)
        res = run_sweep(SweepConfig(**TINY), ex, progress=lambda i, n, s: calls.append((i, n, s)), tasks=4)
        assert len(ex._shared) == 1  # the prepared data went through share(): once per worker
        assert ex.workers == 2
        with pytest.raises(ValueError, match="invalid literal"):  # a task's own error passes through as is
            ex.submit(int, "x").result()
    assert _json(res) == reference
    assert [c for c in calls if c[2] == "quantize + identify"][-1][:2] == (4, 4)
    assert [c for c in calls if c[2] == "MPC closed loops"][-1][:2] == (3, 3)
    assert any("2 worker(s)" in n for n in notes)


@pytest.mark.cluster
def test_local_cluster_matches_in_process(reference):
    _need_distributed()
    with make_executor("local:2") as ex:
        res = run_sweep(SweepConfig(**TINY), ex, tasks=4)
    assert _json(res) == reference


@pytest.mark.cluster
def test_without_share_same_numbers(cluster, reference):
    with make_executor(cluster, share_data=False) as ex:
        assert getattr(ex, "share", None) is None
        assert _json(run_sweep(SweepConfig(**TINY), ex, tasks=4)) == reference


@pytest.mark.cluster
def test_wrong_address_is_one_clear_line():
    _need_distributed()
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    with pytest.raises(ConfigError, match=rf"cannot reach a scheduler at tcp://127.0.0.1:{port} within 2 s") as ei:
        with make_executor(f"tcp://127.0.0.1:{port}", connect_timeout=2):
            pass
    assert "\n" not in str(ei.value)
    assert time.monotonic() - t0 < 20


@pytest.mark.cluster
def test_lost_worker_is_rerun_and_losing_all_is_reported(tmp_path, reference):
    _need_distributed()
    big = dict(TINY, trajectories=60, steps=1000)
    expect = _json(run_sweep(SweepConfig(**big)))
    with dask_cluster(tmp_path) as (address, wprocs, _):
        with make_executor(address, stall_timeout=3, connect_timeout=5) as ex:
            def kill_one(i, n, stage):
                if wprocs[1].poll() is None:
                    os.killpg(wprocs[1].pid, signal.SIGKILL)

            res = run_sweep(SweepConfig(**big), ex, progress=kill_one, tasks=6)
            assert wprocs[1].poll() is not None
            assert _json(res) == expect  # the scheduler reran the lost tasks on the other worker

            os.killpg(wprocs[0].pid, signal.SIGKILL)
            wprocs[0].wait(10)
            end = time.monotonic() + 20
            while ex.workers and time.monotonic() < end:  # the scheduler notices the closed connection
                time.sleep(0.05)
            t0 = time.monotonic()
            with pytest.raises(ClusterError, match="no workers") as ei:
                run_sweep(SweepConfig(**dict(TINY, data_seed=5)), ex, tasks=4)
            assert "\n" not in str(ei.value)
            assert time.monotonic() - t0 < 30


@pytest.mark.cluster
def test_lost_scheduler_is_one_clear_line(tmp_path):
    _need_distributed()
    with dask_cluster(tmp_path, workers=1) as (address, _, sched):
        with make_executor(address, stall_timeout=3) as ex:
            def kill_scheduler(i, n, stage):
                if sched.poll() is None:
                    os.killpg(sched.pid, signal.SIGKILL)

            t0 = time.monotonic()
            with pytest.raises(ClusterError, match="scheduler") as ei:
                run_sweep(SweepConfig(**dict(TINY, trajectories=60, steps=1000)), ex, progress=kill_scheduler, tasks=6)
            assert "\n" not in str(ei.value)
            assert time.monotonic() - t0 < 30


def test_missing_distributed_says_which_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ConfigError, match=r"pip install 'qsid\[distributed\]'"):
        with make_executor("local:1"):
            pass


@pytest.mark.cluster
def test_benchmark_script_runs_and_all_executors_agree(capsys):
    _need_distributed()
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import bench_distributed
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    out = bench_distributed.main(["--quick", "--repeats", "1", "--probe-tasks", "3"])
    assert [r["identical"] for r in out["runs"]] == [True] * 4
    assert out["bytes_shipped"]["no_share"] == 2 * out["tasks"] * out["prep_bytes"]
    assert out["probe"]["per_task_shipped_s"] > 0
    assert "RESULT" in capsys.readouterr().out
