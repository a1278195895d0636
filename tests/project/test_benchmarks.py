"""Smoke tests of benchmarks/: the scripts import, run on tiny problems and their correctness checks pass.

No timing assertions: timings on shared machines are noise; only the numbers the
benchmarks compare (identified models, costs, applied inputs) are checked.
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

# slow: runs the benchmarks' quick modes
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benchmarks"
if str(BENCH) not in sys.path:
    sys.path.insert(0, str(BENCH))

import bench_mpc  # noqa: E402
import bench_sweep  # noqa: E402

TINY = dict(
    system="dc-motor", bits=(1, 4, 9), realizations=3, trajectories=4, steps=60, horizon=4, mpc_steps=6, u_max=1.0
)


@pytest.mark.parametrize("osqp_setup", ["model", "step"])
def test_naive_sweep_matches_engine(osqp_setup):
    d = bench_sweep.correctness_check(TINY, osqp_setup=osqp_setup)
    assert d["max_abs_diff_AB"] < 1e-9
    assert d["max_rel_diff_cost"] < 1e-7
    assert d["failure_mismatches"] == 0
    assert d["loops_compared"] > 0


def test_naive_subset_of_realizations_uses_the_engines_streams():
    d = bench_sweep.correctness_check(TINY, realizations=[2])
    assert d["max_abs_diff_AB"] < 1e-9


def test_executors_give_identical_sweeps():
    cfg = bench_sweep.make_config(TINY)
    res = {}
    for kind in ("inline", "thread", "process-1blas"):
        res[kind] = bench_sweep.time_fast(cfg, kind, 1)["result"]
    assert bench_sweep.executor_agreement(res) == 0.0


def test_bench_sweep_quick_main_prints_result(capsys):
    out = bench_sweep.main(["--quick", "--executors", "inline,thread", "--naive-osqp", "model"])
    text = capsys.readouterr().out
    line = [ln for ln in text.splitlines() if ln.startswith("RESULT ")][-1]
    data = json.loads(line[len("RESULT ") :])
    assert data["benchmark"] == "bench_sweep" and data["quick"]
    assert data["correctness"]["max_abs_diff_AB"] < 1e-9
    assert set(data["fast"]) == {"inline", "thread"}
    # qsid sweep as a user runs it (a new process), beside the naive loop, with the engine's very numbers
    assert data["cli"]["same_result_as_engine"] is True
    assert len(data["cli"]["runs"]) == 1 and data["cli"]["runs"][0]["cpu"] > 0
    assert data["cli"]["naive_over_cli"]["model"] > 0
    assert out["naive"]["model"]["measured_realizations"] == bench_sweep.QUICK["realizations"]


def test_extrapolation_is_linear_in_realizations():
    nv = dict(realizations=[0, 1], t_fixed=1.0, t_loop=4.0)
    assert bench_sweep.extrapolate(nv, 10) == pytest.approx(1.0 + 20.0)


def test_mpc_engine_variants_agree_and_use_both_paths():
    for c in bench_mpc.cases(quick=True):
        pb = bench_mpc.Problem(**c)
        r = bench_mpc.benchmark_problem(pb, list(bench_mpc.ENGINE), 1, 1)
        a, b = r[bench_mpc.ENGINE[0]], r[bench_mpc.ENGINE[1]]
        assert np.abs(a["inputs"] - b["inputs"]).max() < 1e-9
        assert a["qp_steps"] == b["qp_steps"]
        if c["case"] == "constrained":
            assert a["qp_steps"] > 0  # the input bound is active: the QP path is exercised
            assert np.abs(a["inputs"]).max() == pytest.approx(c["u_max"])
        else:
            assert a["qp_steps"] == 0


@pytest.mark.parametrize("peer", ["cvxpy+OSQP tight (eps 1e-9)", "do-mpc+IPOPT tight (tol 1e-12)"])
@pytest.mark.slow
def test_mpc_peers_agree_with_engine(peer):
    pytest.importorskip("cvxpy" if "cvxpy" in peer else "do_mpc")
    res = bench_mpc.check_agreement(quick=True, solvers=[bench_mpc.ENGINE[0], peer])
    assert res, "no cases ran"
    for problem, r in res.items():
        assert r[peer]["max_abs_du"] < bench_mpc.TOL, (problem, r[peer])


def test_bench_mpc_quick_main_prints_result(capsys, tmp_path):
    saved = tmp_path / "out.txt"
    bench_mpc.main(["--quick", "--skip", "do-mpc", "--engine-repeats", "1", "--save", str(saved)])
    text = capsys.readouterr().out
    line = [ln for ln in text.splitlines() if ln.startswith("RESULT ")][-1]
    data = json.loads(line[len("RESULT ") :])
    assert data["benchmark"] == "bench_mpc"
    assert {p["case"] for p in data["problems"]} == {"letter", "constrained"}
    for p in data["problems"]:
        assert p["solvers"]["engine run_closed_loops"]["max_abs_du"] == 0.0
    stage = data["saturated_stage"]  # the compiled loop beside the per-step OSQP loops, on the same models
    assert stage["qp_steps"] > 0 and data["all_agree"]
    assert all(r["max_abs_du_vs_osqp"] <= bench_mpc.TOL for r in stage["rows"].values())
    # --save: the same output after a header naming the command, the machine's load and the code
    head, rest = saved.read_text().split("\n", 2)[:2], saved.read_text().split("\n", 2)[2]
    assert head[0].startswith("# qsid benchmark output: bench") and "load average" in head[1]
    assert rest.strip() == text.strip()


@pytest.mark.parametrize(
    "name",
    [
        "bench_mpc.txt",
        "bench_dashboard.txt",
        "bench_dashboard_inprocess.txt",
        "bench_dashboard_inprocess_before.txt",
        "bench_kernels.txt",
        "bench_koopman.txt",
        "bench_koopman_before.txt",
        "bench_sweep.txt",
    ],
)
def test_the_benchmark_outputs_in_the_docs_were_saved_by_the_benchmarks(name):
    # docs/performance.rst includes these files verbatim: each is a benchmark's own --save output
    path = ROOT / "docs" / "perf" / name
    text = path.read_text(encoding="utf-8")
    assert text.startswith("# qsid benchmark output: bench_") and "load average at start" in text
    assert f"perf/{name}" in (ROOT / "docs" / "performance.rst").read_text(encoding="utf-8")


def test_bench_kernels_times_both_kernels_on_the_same_sums(capsys):
    import bench_kernels

    from qsid_core.quantization import kernels

    if not kernels.AVAILABLE:
        pytest.skip(kernels.REASON)
    assert bench_kernels.main(["--repeat", "1"]) == 0
    rows = [r.split() for r in capsys.readouterr().out.splitlines()[2:]]
    assert [r[0] for r in rows] == [name for name, _, _ in bench_kernels.SIZES]
    for r in rows:  # generic median, generated median, ratio, largest relative difference of the sums
        generic, generated, ratio, diff = float(r[3]), float(r[5]), float(r[7]), float(r[8])
        # the ratio is printed to 0.01 from the unrounded medians, the times to 0.1 ms
        slack = 0.005 + (generated / generic) * (0.05 / generated + 0.05 / generic) + 1e-9
        assert generic > 0 and generated > 0 and ratio == pytest.approx(generated / generic, abs=slack)
        assert diff < 1e-12


def test_blas_helper_reports_and_limits_threads():
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        assert set(bench_mpc.blas_threads().values()) <= {1}
    th = bench_sweep.blas_threads()
    assert isinstance(th, dict)
    assert all(isinstance(v, int) and v >= 1 for v in th.values())


@pytest.mark.slow
def test_bench_speed_quick_sections_agree(capsys):
    import bench_speed

    data = bench_speed.main(["--quick", "--skip", "numba,sweep"])
    mpc = data["saturated_mpc"]
    assert mpc["qp_steps"] == mpc["qp_steps_osqp"] > 0  # the bound is active: both engines solve QPs
    assert mpc["max_abs_du"] < 1e-8 and mpc["failure_mismatches"] == 0
    text = capsys.readouterr().out
    assert "target >= 25x" in text
    if data["numba"]:
        ident = data["identification"]
        assert ident["fused kernel floor"]["best"] > 0 and ident["ratio_engine_to_floor"] > 0
        assert "target <= 1.5x" in text


def test_bench_bits_quick_prints_its_measured_ratio(capsys):
    import bench_bits

    # the smallest run: one system, one timed run of each command and no untimed warm-up run before it (the
    # kernels are compiled by then: CI's warm-up, the tests before); what is checked is that it measures
    assert bench_bits.main(["--quick", "--repeats", "1", "--no-warm", "--systems", "dc-motor"]) == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("RESULT ")][-1]
    data = json.loads(line[len("RESULT ") :])
    r = data["results"][0]
    assert data["warm"] is False and all(len(v) == 1 for v in r["all_s"].values()), data
    assert r["ratio_bits_to_sweep"] == r["median_s"]["bits"] / r["median_s"]["sweep"] > 0


def test_bench_budget_quick_prints_its_measured_ratio(capsys):
    import bench_budget

    assert bench_budget.main(["--quick"]) == 0
    line = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("RESULT ")][-1]
    r = json.loads(line[len("RESULT ") :])
    assert r["ratio"] == pytest.approx(r["budget_s"] / r["sweep_s"], rel=0.01) and r["largest_runs"] == 83
    assert r["cpu_ratio"] == pytest.approx(r["budget_cpu_s"] / r["sweep_cpu_s"], rel=0.01)
    assert r["bits"] == [2, 4, 8, 16] and r["realizations"] == 3 and r["b_knee"] in r["bits"]


@pytest.mark.slow
def test_fuzz_engine_counts_every_call_and_passes(capsys):
    import fuzz_engine

    code = fuzz_engine.main(["--examples", "3", "-k", "theorem1 or quantizer_demo"])
    out = capsys.readouterr().out
    data = json.loads(out.splitlines()[-1].removeprefix("RESULT "))
    assert code == 0 and data["bad"] == {"other exception": 0, "hang": 0, "unflagged NaN": 0}
    assert sum(data["counts"]["theorem1_prediction"].values()) >= 3


def test_bench_follow_runs_with_a_few_followers(capsys):
    import bench_follow

    assert bench_follow.main(["--followers", "2", "--rounds", "1", "--workers", "0"]) == 0
    out = capsys.readouterr().out
    rows = [ln for ln in out.splitlines() if ln.startswith(("0 followers", "2 followers"))]
    assert len(rows) == 3 and "-" not in rows[1].split()[4:6]  # the followers' lag was measured


def test_bench_koopman_dashboard_quick_mode_agrees(capsys):
    import bench_koopman_dashboard

    assert bench_koopman_dashboard.main(["--quick", "--repeat", "1"]) == 0
    assert "same verdicts: yes" in capsys.readouterr().out
