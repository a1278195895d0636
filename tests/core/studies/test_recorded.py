"""Your own recorded data: arrays, .npz and .csv in, LS and BCLS at each b against the unquantized LS model
(or a given system), every bad file one clear line (``qsid identify --data FILE``)."""

import csv
import json

import numpy as np
import pytest

from app.cli import main
from qsid_core import ConfigError, QuantizerSpec, identify_recorded, load_recorded, simulate
from qsid_core.plant.systems import boeing747
from qsid_core.studies.recorded import dataset_from_arrays


@pytest.fixture(scope="module")
def data():
    return simulate(boeing747(), 30, 300, seed=2)


def _write_csv(path, x, u, drop_last_u=True):
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        n, m = x.shape[2], u.shape[2]
        w.writerow(["run", "t"] + [f"x{i + 1}" for i in range(n)] + [f"u{i + 1}" for i in range(m)])
        for r in range(x.shape[0]):
            for t in range(x.shape[1]):
                us = [repr(float(v)) for v in u[r, t]] if t < u.shape[1] else ([""] * m if drop_last_u else ["0"] * m)
                w.writerow([r, t] + [repr(float(v)) for v in x[r, t]] + us)


def test_arrays_npz_and_csv_give_the_same_numbers(data, tmp_path):
    a = identify_recorded((data.states, data.inputs), "3,6", realizations=2).to_dict()
    np.savez(tmp_path / "d.npz", x=data.states, u=data.inputs)
    _write_csv(tmp_path / "d.csv", data.states, data.inputs)
    for name in ("d.npz", "d.csv"):
        assert identify_recorded(load_recorded(tmp_path / name), "3,6", realizations=2).to_dict() == a
    r3 = a["results"][0]
    assert a["reference"] == "LS on the unquantized data"
    assert r3["bcls"]["err_A"]["mean"] < 0.5 * r3["ls"]["err_A"]["mean"]  # BCLS removes most of the bias


def test_reference_system_and_its_shape(data):
    r = identify_recorded(data, "4", realizations=2, system=boeing747(), quantizer=QuantizerSpec(dither="tpdf"))
    assert r.reference == "boeing747" and np.array_equal(r.A_ref, boeing747().A)
    from qsid_core.plant.systems import dc_motor

    with pytest.raises(ConfigError, match="has 3 states and 2 inputs; the data have 4 and 2"):
        identify_recorded(data, "4", system=dc_motor())


def test_bad_data_are_one_clear_error(data, tmp_path):
    x = data.states.copy()
    x[1, 5, 2] = np.nan
    with pytest.raises(ConfigError, match=r"NaN or infinite \(first: run 2, step 5, channel 3\)"):
        dataset_from_arrays(x, data.inputs)
    with pytest.raises(ConfigError, match="runs of different lengths"):
        dataset_from_arrays([np.zeros((5, 2)), np.zeros((6, 2))], [np.zeros((4, 1)), np.zeros((5, 1))])
    with pytest.raises(ConfigError, match="steps \\+ 1 states and steps inputs"):
        dataset_from_arrays(data.states, data.states[:, :, :2])
    np.savez(tmp_path / "no_u.npz", x=data.states)
    with pytest.raises(ConfigError, match="missing u"):
        load_recorded(tmp_path / "no_u.npz")
    (tmp_path / "cols.csv").write_text("run,time,x1,u1\n0,0,1,1\n")
    with pytest.raises(ConfigError, match="columns must be run, t, x1..xn, u1..um"):
        load_recorded(tmp_path / "cols.csv")
    _write_csv(tmp_path / "ragged.csv", data.states[:2], data.inputs[:2])
    with (tmp_path / "ragged.csv").open("a") as f:
        f.write("9,0,1,1,1,1,0,0\n9,1,1,1,1,1,,\n")
    with pytest.raises(ConfigError, match="runs of different lengths"):
        load_recorded(tmp_path / "ragged.csv")
    (tmp_path / "d.txt").write_text("x")
    with pytest.raises(ConfigError, match="give a .npz"):
        load_recorded(tmp_path / "d.txt")


def test_qsid_identify_data_file(data, tmp_path, capsys):
    np.savez(tmp_path / "d.npz", x=data.states, u=data.inputs)
    code = main(["identify", "--data", str(tmp_path / "d.npz"), "--bits", "3,6", "--realizations", "2", "--json", "-q"])
    out, err = capsys.readouterr()
    assert code == 0, err
    d = json.loads(out)
    assert [r["bits"] for r in d["results"]] == [3, 6] and d["runs"] == 30 and d["steps"] == 300
    code = main(["identify", "--data", str(tmp_path / "d.npz"), "--bits", "3", "--system", "boeing747", "-q"])
    out, err = capsys.readouterr()
    assert code == 0 and "errors against boeing747" in out and "BCLS err_A" in out
    code = main(["identify", "--data", str(tmp_path / "missing.csv")])
    _, err = capsys.readouterr()
    assert code == 2 and "does not exist" in err and len(err.strip().splitlines()) == 1
