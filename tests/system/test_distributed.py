"""Sweeps on a real dask.distributed cluster (app/distributed.py).

The cluster tests start ``dask scheduler`` and ``dask worker`` as separate
processes on 127.0.0.1 (random ports, no dashboards, one thread per worker),
run tiny sweeps through :func:`app.dask_cluster.make_executor` and compare the
JSON with the in-process run (timings excluded). They skip only when the
``distributed`` package is missing; with ``QSID_REQUIRE_DISTRIBUTED=1`` (set by
.ci/run) a missing package fails instead.
"""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path

import pytest
from support import HANG_S, dask_cluster, wait_until
from support import need_distributed as _need_distributed

from app.dask_cluster import make_executor
from app.distributed import ClusterError, DaskExecutor, parse_dask_spec
from qsid_core import SweepConfig, run_sweep
from qsid_core.errors import ConfigError

TINY = dict(bits=(2, 5, 9), realizations=8, trajectories=12, steps=150)
#: How long a broken cluster may stall before the executor gives up; it also bounds how long sharing
#: an object with the workers may take, so it is generous (a busy machine only makes a test slower).
STALL_S = 20.0
ROOT = Path(__file__).resolve().parents[2]


def _json(res) -> str:
    d = res.to_dict()
    d.pop("timing_s")
    return json.dumps(d, sort_keys=True)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    _need_distributed()
    with dask_cluster(tmp_path_factory.mktemp("dask")) as (address, _, _):
        yield address


@pytest.fixture(scope="module")
def reference():
    return _json(run_sweep(SweepConfig(**TINY)))


# ----- parsing (no dask needed) -------------------------------------------------------------
@pytest.mark.parametrize(
    "spec, workers, address",
    [
        ("local:3", 3, None),
        ("tcp://127.0.0.1:8786", None, "tcp://127.0.0.1:8786"),
        (" tcp://node-7.cluster:9000 ", None, "tcp://node-7.cluster:9000"),
    ],
)
def test_parse_dask_spec(spec, workers, address):
    p = parse_dask_spec(spec)
    assert (p.workers, p.address) == (workers, address)


def test_parse_local_uses_the_cores():
    assert parse_dask_spec("local").workers >= 1


@pytest.mark.parametrize(
    "spec, match",
    [
        ("local:0", "between 1 and"),
        ("local:x", "integer"),
        ("udp://1.2.3.4:5", "cannot read"),
        ("tcp://127.0.0.1", "cannot read"),
        ("tcp://127.0.0.1:70000", "port"),
        ("", "cannot read"),
    ],
)
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
    with pytest.raises(ConfigError, match=rf"cannot reach a scheduler at tcp://127.0.0.1:{port} within 2 s") as ei:
        with make_executor(f"tcp://127.0.0.1:{port}", connect_timeout=2):
            pass
    assert "\n" not in str(ei.value)


@pytest.mark.cluster
def test_lost_worker_is_rerun_and_losing_all_is_reported(tmp_path, reference):
    _need_distributed()
    big = dict(TINY, trajectories=60, steps=1000)
    expect = _json(run_sweep(SweepConfig(**big)))
    with dask_cluster(tmp_path) as (address, wprocs, _):
        with make_executor(address, stall_timeout=STALL_S, connect_timeout=HANG_S) as ex:

            def kill_one(i, n, stage):
                if wprocs[1].poll() is None:
                    os.killpg(wprocs[1].pid, signal.SIGKILL)

            res = run_sweep(SweepConfig(**big), ex, progress=kill_one, tasks=6)
            assert wprocs[1].poll() is not None
            assert _json(res) == expect  # the scheduler reran the lost tasks on the other worker

            os.killpg(wprocs[0].pid, signal.SIGKILL)
            wprocs[0].wait(HANG_S)
            wait_until(lambda: not ex.workers, "the scheduler noticed the closed connection", every=0.05)
            with pytest.raises(ClusterError, match="no workers") as ei:
                run_sweep(SweepConfig(**dict(TINY, data_seed=5)), ex, tasks=4)
            assert "\n" not in str(ei.value)


@pytest.mark.cluster
def test_lost_scheduler_is_one_clear_line(tmp_path):
    _need_distributed()
    with dask_cluster(tmp_path, workers=1) as (address, _, sched):
        with make_executor(address, stall_timeout=STALL_S) as ex:

            def kill_scheduler(i, n, stage):
                if sched.poll() is None:
                    os.killpg(sched.pid, signal.SIGKILL)

            with pytest.raises(ClusterError, match="scheduler") as ei:
                run_sweep(SweepConfig(**dict(TINY, trajectories=60, steps=1000)), ex, progress=kill_scheduler, tasks=6)
            assert "\n" not in str(ei.value)


def test_missing_distributed_says_which_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(ConfigError, match=r'pip install "\.\[distributed\]"'):
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
