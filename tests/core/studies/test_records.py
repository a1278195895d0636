"""Per-realization export (qsid_core/records.py): rows, columns, CSV and pandas."""

import csv
import math
import sys

import numpy as np
import pytest

from qsid_core import Experiment, MPCConfig, QuantizerSpec, SweepConfig, run_sweep
from qsid_core.errors import ConfigError
from qsid_core.studies.records import (
    COLUMNS,
    RealizationRecord,
    experiment_records,
    realization_records,
    to_columns,
    to_pandas,
    write_csv,
)

# no guard band, so that the overload column has something to show (the engine's default guards against it)
CFG = dict(
    bits=(1, 4, 10),
    realizations=5,
    trajectories=10,
    steps=150,
    mpc=MPCConfig(horizon=5, steps=15),
    quantizer=QuantizerSpec(guard=False),
)


@pytest.fixture(scope="module")
def result():
    return run_sweep(SweepConfig(**CFG))


def test_one_row_per_b_and_realization_with_the_sweeps_numbers(result):
    recs = realization_records(result)
    assert len(recs) == 3 * 5
    assert COLUMNS == (
        "system",
        "bits",
        "estimator",
        "realization",
        "err_A",
        "err_B",
        "overload",
        "ident_failed",
        "bcls_fallback",
        "mpc_status",
        "mpc_cost",
        "mpc_predicted_cost",
        "final_state_norm",
        "outcome",
        "closed_loop_spectral_radius",
        "controllability",
    )
    assert [(r.bits, r.realization) for r in recs] == [(b, i) for b in (1, 4, 10) for i in range(5)]
    for b in result.bits:
        rows = [r for r in recs if r.bits == b]
        ident, lp = result.identification[b], result.loops[b]
        np.testing.assert_array_equal([r.err_A for r in rows], ident.err_A)
        np.testing.assert_array_equal([r.err_B for r in rows], ident.err_B)
        np.testing.assert_array_equal([r.overload for r in rows], ident.overload)
        np.testing.assert_array_equal([r.mpc_cost for r in rows], lp.cost)
        np.testing.assert_array_equal([r.final_state_norm for r in rows], lp.final_state_norm)
        # the summary JSON is the mean of these rows
        s = result.summary(b)
        assert np.nanmean([r.err_A for r in rows]) == pytest.approx(s["err_A"]["mean"], rel=1e-12)
        kinds = {}
        for r in rows:
            if r.mpc_status != "ok":
                kinds[r.mpc_status] = kinds.get(r.mpc_status, 0) + 1
        assert kinds == s["mpc_cost"]["failures"]
    assert {r.estimator for r in recs} == {"ls"} and {r.system for r in recs} == {"dc-motor"}
    assert recs[0].overload > 10 * recs[-1].overload  # b = 1 overloads far more than b = 10


def test_without_mpc_the_loop_columns_say_off():
    res = run_sweep(SweepConfig(**dict(CFG, mpc=None)))
    recs = realization_records(res)
    assert len(recs) == 15
    assert all(r.mpc_status == "off" and math.isnan(r.mpc_cost) and math.isnan(r.final_state_norm) for r in recs)


def test_two_estimators_on_the_same_data(result):
    ex = Experiment(SweepConfig(**CFG))
    recs = experiment_records(ex, CFG["bits"], ("ls", "bcls"))
    assert len(recs) == 2 * 3 * 5
    ls = [r for r in recs if r.estimator == "ls"]
    assert ls == realization_records(result)
    bc = [r for r in recs if r.estimator == "bcls"]
    assert [r.err_A for r in bc] != [r.err_A for r in ls]
    with pytest.raises(ConfigError, match="estimator"):
        experiment_records(ex, (4,), ("ols",))


def test_csv_round_trip(result, tmp_path):
    p = tmp_path / "rows.csv"
    assert write_csv(result, p) == 15
    with open(p, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 15 and tuple(rows[0]) == COLUMNS
    recs = realization_records(result)
    for row, rec in zip(rows, recs):
        assert float(row["err_A"]) == rec.err_A  # repr: exact
        assert row["ident_failed"] in ("true", "false")
        assert (row["mpc_cost"] == "") == math.isnan(rec.mpc_cost)
        assert int(row["bits"]) == rec.bits and row["mpc_status"] == rec.mpc_status


def test_pandas_frame_and_csv_agree(result, tmp_path):
    pd = pytest.importorskip("pandas")
    df = to_pandas(result)
    assert list(df.columns) == list(COLUMNS) and len(df) == 15
    assert df.groupby("bits").size().tolist() == [5, 5, 5]
    p = tmp_path / "rows.csv"
    write_csv(realization_records(result), p)
    back = pd.read_csv(p)
    assert back["ident_failed"].dtype == bool
    np.testing.assert_array_equal(back["err_A"].to_numpy(), df["err_A"].to_numpy())
    np.testing.assert_array_equal(back["mpc_cost"].isna(), df["mpc_cost"].isna())


def test_no_pandas_is_a_clear_error(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas -> ImportError
    with pytest.raises(ImportError, match="to_pandas needs pandas"):
        to_pandas(result)
    cols = to_columns(result)  # the plain table still works
    assert list(cols) == list(COLUMNS) and len(cols["err_A"]) == 15


def test_rejects_other_things(tmp_path):
    with pytest.raises(ConfigError, match="SweepResult or a list of RealizationRecord"):
        write_csv([{"bits": 3}], tmp_path / "x.csv")
    assert isinstance(
        realization_records(run_sweep(SweepConfig(**dict(CFG, bits=(6,), mpc=None))))[0], RealizationRecord
    )
