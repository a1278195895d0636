"""``qsid sweep --dask`` / ``qsid reproduce --dask`` and ``qsid sweep --csv`` (issue 10): the same numbers as
in-process, on a LocalCluster and on a real scheduler + 2 worker processes; one line for a bad --dask."""

from __future__ import annotations

import csv
import json

import pytest
from support import dask_cluster
from support import need_distributed as _need_distributed

from app.cli import main

TINY = ["--trajectories", "12", "--steps", "150", "--realizations", "4", "--bits", "2,5"]


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _results(out: str) -> list:
    return json.loads(out)["results"]


def test_sweep_csv_one_row_per_b_and_realization(capsys, tmp_path):
    f = tmp_path / "rows.csv"
    code, out, err = _run(capsys, "sweep", *TINY, "--json", "--csv", str(f))
    assert code == 0, err
    rows = list(csv.DictReader(f.open()))
    assert len(rows) == 2 * 4 and [r["bits"] for r in rows] == ["2"] * 4 + ["5"] * 4
    assert {"err_A", "err_B", "overload", "mpc_cost", "mpc_status", "final_state_norm"} <= set(rows[0])
    d = _results(out)
    mean_a = sum(float(r["err_A"]) for r in rows[:4]) / 4
    assert mean_a == pytest.approx(d[0]["err_A"]["mean"], rel=1e-12)
    assert "8 rows" in err


def test_csv_is_checked_before_the_run(capsys, tmp_path):
    code, out, err = _run(capsys, "sweep", *TINY, "--csv", str(tmp_path / "a.json"), "--out", str(tmp_path / "a.json"))
    assert code == 2 and "same file" in err and "quantize" not in err
    code, out, err = _run(capsys, "sweep", *TINY, "--csv", "")
    assert code == 2 and "--csv" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--dask", "foo"], "local:N"),
        (["--dask", "local:2", "--workers", "2"], "either --dask or --workers"),
    ],
)
def test_bad_dask_is_one_line(capsys, extra, needle):
    _need_distributed()
    code, out, err = _run(capsys, "sweep", *TINY, "-q", *extra)
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: ") and needle in err, err


@pytest.mark.slow
def test_unreachable_scheduler_is_one_line(capsys):
    _need_distributed()
    code, out, err = _run(capsys, "sweep", *TINY, "-q", "--dask", "tcp://127.0.0.1:9")
    assert code == 2 and len(err.splitlines()) == 1 and "cannot reach a scheduler" in err


@pytest.mark.slow
def test_local_cluster_gives_the_in_process_numbers(capsys, tmp_path):
    _need_distributed()
    code, ref, _ = _run(capsys, "sweep", *TINY, "--json", "-q")
    assert code == 0
    code, out, err = _run(capsys, "sweep", *TINY, "--json", "--dask", "local:2", "--csv", str(tmp_path / "r.csv"))
    assert code == 0, err
    assert _results(out) == _results(ref)
    assert "dask: connected to tcp://127.0.0.1:" in err and "(2 worker(s))" in err


@pytest.mark.slow
def test_real_scheduler_and_two_workers(capsys, tmp_path):
    _need_distributed()
    code, ref, _ = _run(capsys, "sweep", *TINY, "--json", "-q")
    assert code == 0
    with dask_cluster(tmp_path, workers=2) as (address, *_):
        code, out, err = _run(capsys, "sweep", *TINY, "--json", "--dask", address)
        assert code == 0, err
        assert _results(out) == _results(ref) and f"dask: connected to {address} (2 worker(s))" in err
        code, _, err = _run(
            capsys, "reproduce", "--system", "boeing747", "--out", str(tmp_path / "fig"), *TINY, "--dask", address, "-q"
        )
        assert code == 0, err
        assert (tmp_path / "fig" / "index.html").is_file()
