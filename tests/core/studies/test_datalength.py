import dataclasses
import json
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from qsid_core import ConfigError, QuantizerSpec
from qsid_core.studies.datalength import DEFAULT_SAMPLES, DataLengthConfig, run_datalength, runs_and_steps

SHARED = QuantizerSpec(range_mode="shared")  # guard band on (default)


def test_runs_and_steps_rule():
    assert runs_and_steps(1000) == (10, 100)
    assert runs_and_steps(10_000) == (10, 1000)
    assert runs_and_steps(1_000_000) == (1000, 1000)
    assert runs_and_steps(2200) == (10, 220)
    r, s = runs_and_steps(46_400)
    assert s == 1000 and r * s >= 46_400
    assert len(DEFAULT_SAMPLES) == 10 and DEFAULT_SAMPLES[0] == 1000 and DEFAULT_SAMPLES[-1] == 1_000_000


def test_ls_levels_off_on_theorem1_floor_while_bcls_keeps_falling():
    """Boeing, shared range, guard band, b = 10 (measured: LS 1.9e-3 -> 8.2e-4 on the 8.0e-4 floor,
    BCLS 1.2e-3 -> 6.7e-5)."""
    res = run_datalength(
        DataLengthConfig(
            system="boeing747", bits=10, samples=(1000, 10_000, 100_000, 300_000), realizations=3, quantizer=SHARED
        )
    )
    r = {row.samples: row for row in res.rows}
    big, mid, small = r[300_000], r[100_000], r[1000]
    assert big.ls_A.mean == pytest.approx(big.err_A_theory, rel=0.1)
    assert big.ls_A.mean / mid.ls_A.mean > 0.85  # levelled off
    assert small.ls_A.mean > 1.5 * small.err_A_theory  # finite data: above the floor
    assert big.bcls_A.mean < 0.2 * big.err_A_theory  # BCLS goes below the floor
    assert r[10_000].bcls_A.mean / big.bcls_A.mean > 3  # and keeps falling (~T^-1/2: sqrt(30) = 5.5)
    assert all(row.overload_fraction == 0 for row in res.rows)
    d = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    row = d["rows"][0]
    assert row["samples"] == 1000 and row["trajectories"] == 10 and row["steps"] == 100
    assert set(row["ls"]) == {"err_A", "err_B"} and set(row["bcls"]["err_B"]) == {"mean", "std"}
    assert d["config"]["guard"] is True and len(d["eps"]) == 6


def test_one_quantizer_range_for_every_length():
    res = run_datalength(DataLengthConfig(system="dc-motor", bits=6, samples=(500, 5000), realizations=2))
    assert res.eps.shape == (5,)
    # same eps, so Theorem 1's floor moves only with Sigma of the data (runs are nested prefixes)
    assert all(np.isfinite(row.err_A_theory) for row in res.rows)


def test_executor_progress_and_same_numbers():
    cfg = DataLengthConfig(system="boeing747", bits=6, samples=(1000, 4000), realizations=4, quantizer=SHARED)
    calls = []
    a = run_datalength(cfg, progress=lambda d, t, s: calls.append((d, t, s)), tasks=2)
    with ThreadPoolExecutor(2) as pool:
        b = run_datalength(cfg, executor=pool, tasks=2)
    assert [c[:2] for c in calls] == [(1, 4), (2, 4), (3, 4), (4, 4)] and "T = 1000" in calls[0][2]
    for ra, rb in zip(a.rows, b.rows):
        assert ra.ls_A.mean == pytest.approx(rb.ls_A.mean, rel=1e-12)


@pytest.mark.parametrize("kind", ["callable", "event"])
def test_cancellation_between_lengths(kind):
    cfg = DataLengthConfig(system="boeing747", bits=6, samples=(1000, 2000, 4000), realizations=2, quantizer=SHARED)
    ev = threading.Event()
    done = []

    def progress(d, t, s):
        done.append(d)
        if d == 1:
            ev.set()

    stop = ev if kind == "event" else ev.is_set
    res = run_datalength(cfg, progress=progress, should_stop=stop, tasks=1)
    assert res.cancelled and len(res.rows) == 1 and done == [1]


def test_no_dither_runs_one_realization():
    cfg = DataLengthConfig(
        system="boeing747", bits=4, samples=(1000,), realizations=5, quantizer=QuantizerSpec(dither="none")
    )
    res = run_datalength(cfg)
    assert res.rows[0].ls_A.std == 0.0


@pytest.mark.parametrize(
    "kw",
    [
        dict(samples=()),
        dict(samples=(10,)),
        dict(samples=("x",)),
        dict(bits=0),
        dict(realizations=0),
        dict(input_amplitude=-1.0),
    ],
)
def test_bad_config(kw):
    with pytest.raises(ConfigError):
        DataLengthConfig(**kw)


def test_process_pool_executor():
    from concurrent.futures import ProcessPoolExecutor

    cfg = DataLengthConfig(system="boeing747", bits=6, samples=(1000,), realizations=2, quantizer=SHARED)
    with ProcessPoolExecutor(2) as pool:
        b = run_datalength(cfg, executor=pool, tasks=2)
    a = run_datalength(cfg, tasks=2)
    assert a.rows[0].bcls_A.mean == pytest.approx(b.rows[0].bcls_A.mean, rel=1e-12)


SMALL = dict(system="dc-motor", bits=5, samples=(1000, 4000), realizations=2)


def test_the_sweeps_what_ifs_reach_the_study():
    """State amplitude, sensor noise (and BCLS told of it) and per-channel word lengths act as in a sweep."""
    base = run_datalength(DataLengthConfig(**SMALL))
    assert DataLengthConfig().what_ifs() == {} and "noise" not in base.to_dict()["config"]  # the record as before
    amp = run_datalength(DataLengthConfig(**SMALL, state_amplitude=5.0))
    assert amp.rows[0].ls_A.mean != base.rows[0].ls_A.mean and amp.eps[2] > 4 * base.eps[2]  # a wider range
    exact = run_datalength(DataLengthConfig(**SMALL, input_bits="exact"))  # dc-motor: 3 states, 2 inputs
    assert np.all(exact.eps[3:] == 0.0) and np.all(exact.eps[:3] == base.eps[:3])  # the inputs not quantized
    assert exact.rows[-1].err_B_theory < base.rows[-1].err_B_theory
    one = run_datalength(DataLengthConfig(**SMALL, state_bits=(3, "b", "exact")))
    assert one.eps[2] == 0.0 and one.eps[0] > base.eps[0] and one.eps[1] == base.eps[1]
    noisy = DataLengthConfig(**SMALL, noise=(0.0, 0.0, 0.5))  # on the third state, eps 0.07 without it
    told = run_datalength(dataclasses.replace(noisy, noise_known=True))
    untold = run_datalength(noisy)
    assert untold.rows[-1].err_A_theory > 2 * base.rows[-1].err_A_theory  # Theorem 1's limit adds sigma^2
    assert told.rows[-1].bcls_A.mean != untold.rows[-1].bcls_A.mean  # BCLS corrects the noise it is told of
    assert told.rows[-1].ls_A.mean == untold.rows[-1].ls_A.mean  # LS does not hear of it
    assert told.to_dict()["config"]["noise"] == [0.0, 0.0, 0.5] and told.to_dict()["config"]["noise_known"] is True


@pytest.mark.parametrize("kw", [dict(input_bits=(4, 4, 4)), dict(state_bits=(4, 4)), dict(noise=(0.1, 0.1))])
def test_a_what_if_of_the_wrong_size_is_one_error_before_any_work(kw):
    with pytest.raises(ConfigError):
        run_datalength(DataLengthConfig(**SMALL, **kw))


def test_from_sweep_takes_every_field_the_configs_share():
    from qsid_core import SweepConfig

    shared = {f.name for f in dataclasses.fields(SweepConfig)} & {f.name for f in dataclasses.fields(DataLengthConfig)}
    assert shared == {
        "system",
        "bits",
        "realizations",
        "quantizer",
        "input_amplitude",
        "data_seed",
        "dither_seed",
        "state_amplitude",
        "noise",
        "noise_known",
        "input_bits",
        "state_bits",
    }
    sweep = SweepConfig(
        system="boeing747",
        realizations=7,
        quantizer=SHARED,
        input_amplitude=0.5,
        data_seed=3,
        dither_seed=4,
        state_amplitude=2.0,
        noise=0.01,
        noise_known=True,
        input_bits="exact",
        state_bits=("b", 6, "b", "b", "b"),
    )
    study = DataLengthConfig.from_sweep(sweep, bits=6)
    assert study.bits == 6 and all(getattr(study, k) == getattr(sweep, k) for k in shared - {"bits"})


def test_the_cache_key_is_generated_from_every_field():
    from qsid_core import get_system
    from qsid_core.studies import datalength_key

    system = get_system("dc-motor")
    base = DataLengthConfig(**SMALL)
    changes = dict(
        bits=6,
        samples=(1000,),
        realizations=3,
        quantizer=QuantizerSpec(guard=False),
        steps_per_run=500,
        min_runs=5,
        input_amplitude=0.5,
        data_seed=9,
        dither_seed=9,
        state_amplitude=2.0,
        noise=0.01,
        noise_known=True,
        input_bits="exact",
        state_bits=(4,),
    )
    assert set(changes) == {f.name for f in dataclasses.fields(DataLengthConfig)} - {"system"}
    key = datalength_key(base, system)
    assert key == datalength_key(DataLengthConfig(**SMALL), system)
    for name, value in changes.items():
        assert datalength_key(dataclasses.replace(base, **{name: value}), system) != key, name
    assert datalength_key(base, get_system("boeing747")) != key
