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
