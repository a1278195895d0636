import json
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from qsid_core import ConfigError, Experiment, MPCConfig, QuantizerSpec, SweepConfig, fit_slope, parse_bits, run_sweep

SMALL = dict(trajectories=10, steps=200, realizations=4)


def test_parse_bits_forms_and_errors():
    assert parse_bits("2:5") == (2, 3, 4, 5)
    assert parse_bits("6,2,4") == (2, 4, 6)
    assert parse_bits("8") == (8,)
    assert parse_bits(range(1, 4)) == (1, 2, 3)
    for bad in ("5:2", "abc", "0", "40", "", "2:x"):
        with pytest.raises(ConfigError):
            parse_bits(bad)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(realizations=0), "realizations"),
        (dict(trajectories=0), "trajectories"),
        (dict(estimator="ridge"), "estimator"),
        (dict(theta=1.5), "theta"),
        (dict(rho=0.0), "rho"),
        (dict(data_seed=-1), "data seed"),
    ],
)
def test_bad_sweep_config(kw, match):
    with pytest.raises(ConfigError, match=match):
        SweepConfig(**kw)


def test_sweep_result_is_json_ready_and_complete():
    res = run_sweep(SweepConfig(bits="2:6", **SMALL))
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert [r["bits"] for r in d["results"]] == [2, 3, 4, 5, 6]
    for r in d["results"]:
        for k in (
            "eps_x",
            "eps_u",
            "err_A",
            "err_B",
            "err_A_theory",
            "err_B_theory",
            "overload_fraction",
            "mpc_cost",
            "ultimate_bound",
            "final_state_norm",
        ):
            assert k in r
        assert set(r["err_A"]) == {"mean", "std"} and len(r["eps_x"]) == 3 and len(r["eps_u"]) == 2
        assert {"mean", "std", "failed"} <= set(r["mpc_cost"]) and {"mean", "max"} <= set(r["final_state_norm"])
    for k in ("mpc_cost_true_model", "slope_A", "slope_B", "timing_s"):
        assert k in d
    # guard band (default): eps = range / (2^b - 1)
    e = [r["eps_x"][0] for r in d["results"]]
    assert e[0] / e[1] == pytest.approx((2**3 - 1) / (2**2 - 1))


def test_realizations_are_independent_and_reproducible():
    cfg = SweepConfig(bits=(4,), mpc=None, **SMALL)
    a = Experiment(cfg).identification(4)
    b = Experiment(cfg).identification(4)
    np.testing.assert_array_equal(a.err_A, b.err_A)
    assert len(set(np.round(a.err_A, 12))) == SMALL["realizations"]
    c = Experiment(SweepConfig(bits=(4,), mpc=None, dither_seed=7, **SMALL)).identification(4)
    assert not np.array_equal(a.err_A, c.err_A)


def test_executor_gives_same_result_as_inline():
    cfg = SweepConfig(bits="3:5", **SMALL)
    a = run_sweep(cfg)
    with ThreadPoolExecutor(2) as pool:
        b = run_sweep(cfg, executor=pool)
    for bb in cfg.bits:
        np.testing.assert_allclose(a.identification[bb].A_hat, b.identification[bb].A_hat, rtol=1e-12)
        np.testing.assert_allclose(a.loops[bb].cost, b.loops[bb].cost, rtol=1e-12)


def test_process_pool_executor_works():
    from concurrent.futures import ProcessPoolExecutor

    cfg = SweepConfig(bits="4", mpc=None, **SMALL)
    with ProcessPoolExecutor(2) as pool:
        b = run_sweep(cfg, executor=pool)
    a = run_sweep(cfg)
    np.testing.assert_allclose(a.identification[4].err_A, b.identification[4].err_A, rtol=1e-12)


def test_cache_reuse_between_stages():
    shared: dict = {}
    cfg = SweepConfig(bits=(4,), **SMALL)
    ex = Experiment(cfg, cache=shared)
    ex.closed_loops(4)
    n_before = len(shared)
    # a Q change reuses data and identification, adds only new loops
    ex2 = Experiment(SweepConfig(bits=(4,), mpc=MPCConfig(Q=(1.0, 1.0, 1.0)), **SMALL), cache=shared)
    assert ex2.identification(4) is ex.identification(4)
    ex2.closed_loops(4)
    assert len(shared) == n_before + 1
    # a b change reuses the data
    assert ex.with_config(SweepConfig(bits=(6,), **SMALL)).data is ex.data


class _Forgetful(dict):
    """A cache that drops every entry as soon as it is stored (what a shared, bounded cache may do at any moment
    while other tabs store theirs)."""

    def __setitem__(self, key, value):
        pass


class _DropsAfterCheck(dict):
    """Holds entries, but one found by ``in`` is dropped before it can be read (evicted in between)."""

    def __contains__(self, key):
        return self.pop(key, None) is not None


@pytest.mark.parametrize("cache", [_Forgetful, _DropsAfterCheck])
def test_results_never_depend_on_the_cache_keeping_an_entry(cache):
    from qsid_core.studies import predicted_small_gain

    cfg = SweepConfig(bits=(3, 5), mpc=MPCConfig(steps=10), **SMALL)
    ref = Experiment(cfg)
    ex = Experiment(cfg, cache=cache())
    for _ in range(2):  # the second pass reads what the first stored (or finds it gone)
        moms = ex.moments([3, 5])
        assert sorted(moms) == [3, 5] and len(moms[5]) == SMALL["realizations"]
        np.testing.assert_array_equal(ex.identification(5).A_hat, ref.identification(5).A_hat)
        assert ex.theory(3).delta == ref.theory(3).delta
        ex.realized_bound(5)
        ex.overload_effect(3)
        ex.assumptions(5)
        np.testing.assert_array_equal(ex.closed_loops(5).states, ref.closed_loops(5).states)
        assert sorted(ex.closed_loops_many([3, 5])) == [3, 5]
        ex.true_model_loop()
        assert predicted_small_gain(ex, 3) == predicted_small_gain(ref, 3)


def test_progress_is_reported():
    calls = []
    run_sweep(SweepConfig(bits="2:3", **SMALL), progress=lambda d, t, s: calls.append((d, t, s)))
    stages = {s for _, _, s in calls}
    assert "MPC closed loops" in stages and any("quantize" in s for s in stages)
    assert all(1 <= d <= t for d, t, _ in calls)


def test_no_mpc_sweep():
    res = run_sweep(SweepConfig(bits="4", mpc=None, **SMALL))
    d = res.to_dict()
    assert d["results"][0]["mpc_cost"] is None and d["mpc_cost_true_model"] is None
    with pytest.raises(ConfigError, match="switched off"):
        Experiment(SweepConfig(bits="4", mpc=None, **SMALL)).closed_loops(4)


def test_failures_counted_in_sweep_never_crash():
    # b = 1 shared range on the Boeing with a tiny input bound and a state box: some realizations fail
    res = run_sweep(
        SweepConfig(
            system="boeing747",
            bits="1:2",
            quantizer=QuantizerSpec(range_mode="shared"),
            mpc=MPCConfig(x_max=0.5, steps=10),
            **SMALL,
        )
    )
    for r in res.to_dict()["results"]:
        assert r["mpc_cost"]["failed"] == sum(r["mpc_cost"]["failures"].values())
    assert any(r["mpc_cost"]["failed"] > 0 for r in res.to_dict()["results"])


def test_fit_slope():
    b = np.arange(1, 9)
    assert fit_slope(b, 10.0 ** (-0.3 * b)) == pytest.approx(-0.3)
    assert math.isnan(fit_slope([1], [1.0]))


def test_parse_bits_step_and_specific_messages():
    assert parse_bits("2:10:4") == (2, 6, 10)
    with pytest.raises(ConfigError, match="empty"):
        parse_bits("5:2")
    with pytest.raises(ConfigError, match="step"):
        parse_bits("2:8:0")


def test_inline_executor_runs_lazily_so_progress_is_live():
    from qsid_core import InlineExecutor

    ran = []
    ex = InlineExecutor()
    f1 = ex.submit(lambda: ran.append(1) or 1)
    f2 = ex.submit(lambda: ran.append(2) or 2)
    assert ran == []
    assert f1.result() == 1 and ran == [1]
    assert f2.result() == 2 and ran == [1, 2]
    boom = ex.submit(lambda: 1 / 0)
    assert isinstance(boom.exception(), ZeroDivisionError)


def test_singular_realization_is_recorded_not_fatal():
    # no dither, 1 bit, shared range: quantized data collapse and Psi Psi^T is singular
    res = run_sweep(
        SweepConfig(
            bits="1", quantizer=QuantizerSpec(dither="none", range_mode="shared"), mpc=MPCConfig(steps=5), **SMALL
        )
    )
    ident = res.identification[1]
    row = res.to_dict()["results"][0]
    assert row["ident_failures"] == int(ident.failed.sum())
    if ident.failed.any():
        assert any("identification failed" in n for n in ident.notes)
        assert row["mpc_cost"]["failures"].get("ident", 0) == int(ident.failed.sum())


def test_eigenvalues_skip_failed_realizations():
    ex = Experiment(SweepConfig(bits="4", mpc=None, **SMALL))
    ident = ex.identification(4)
    assert ident.eigenvalues.shape == (SMALL["realizations"], 3)
    ident.failed[0] = True
    ident.A_hat[0] = np.nan
    assert ident.eigenvalues.shape == (SMALL["realizations"] - 1, 3)
    assert np.allclose(np.sort(np.abs(ex.system.eigenvalues)), np.sort(np.abs(np.linalg.eigvals(ex.system.A))))
