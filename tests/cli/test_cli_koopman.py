"""``qsid sweep`` / ``qsid bits`` / ``qsid systems`` with nonlinear plants (Koopman/EDMD)."""

from __future__ import annotations

import json
import sys
import types

import pytest

from app.cli import main

SMALL = ["--trajectories", "200", "--steps", "60", "--realizations", "2", "--bits", "2,4", "--mpc-steps", "60"]


def _strict(text: str):
    def bad(c):
        raise AssertionError(f"non-JSON constant {c}")

    return json.loads(text, parse_constant=bad)


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_systems_lists_the_nonlinear_presets(capsys):
    code, out, _ = _run(capsys, "systems", "--json")
    items = {d["name"]: d for d in _strict(out)}
    assert code == 0
    for name in ("van-der-pol", "duffing", "pendulum"):
        assert items[name]["nonlinear"] is True and items[name]["n"] == 2 and items[name]["dt"] == 0.05


def test_nonlinear_sweep_json_rows_carry_lifted_errors_prediction_and_loop_outcomes(capsys):
    code, out, err = _run(capsys, "sweep", "--system", "van-der-pol", "--estimator", "bcls", *SMALL, "--json")
    assert code == 0, err
    d = _strict(out)
    assert d["kind"] == "koopman" and d["config"]["lifting"] == "poly:3" and d["config"]["features"] == 10
    assert d["config"]["trajectories"] == 200 and d["config"]["mpc"]["steps"] == 60  # typed options win
    assert "do not apply" in d["certificates"]
    rows = d["results"]
    assert [r["bits"] for r in rows] == [2, 4]
    for r in rows:
        for k in ("err_G", "err_A", "err_B", "prediction_error"):
            assert set(r[k]) == {"mean", "std"} and r[k]["mean"] >= 0
        assert sum(r["closed_loop_outcomes"].values()) == 2 and 0 <= r["stabilized_fraction"] <= 1
        assert 0 <= r["within_radius"] <= 2 and set(r["settled_offset"]) == {"median", "max"}
        assert r["settled_offset"]["median"] <= r["settled_offset"]["max"]
        if r["settled_offset"]["median"] > 1e-6 * 2.0:  # |x0| = 2: above 1e-6 |x0| is bounded, not converged
            assert r["closed_loop_outcomes"]["converged"] < 2
    assert rows[1]["err_G"]["mean"] < rows[0]["err_G"]["mean"]  # more bits, closer to the unquantized EDMD
    assert d["reference"]["settled_offset"] > 0 and d["reference"]["closed_loop_outcome"] == "bounded"


def test_the_nonlinear_table_shows_the_settled_offsets_and_the_reference(capsys):
    code, out, err = _run(capsys, "sweep", "--system", "van-der-pol", "--estimator", "bcls", *SMALL)
    assert code == 0, err
    head = out.splitlines()[1]
    assert "converged" in head and "within radius" in head and "settled offset med/max" in head
    assert "settled offset" in out.split("unquantized EDMD:")[1].splitlines()[0]
    assert "a loop converged when it settles (mean |x| over its last 10 % of steps) within 1e-6 |x0|" in out


def _columns(out: str) -> list[list[str]]:
    """The table's lines split at its columns (found from the dashed rule under the header)."""
    lines = out.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("-  --"))
    spans, pos = [], 0
    for dash in lines[k].split("  "):
        spans.append((pos, pos + len(dash)))
        pos += len(dash) + 2
    body = [ln for ln in lines[k - 1 :] if ln[:1].isdigit() or ln.startswith("b ")]
    assert all(len(ln) == len(lines[k]) for ln in body), "the rows are not as wide as the rule: columns drift"
    assert all(ln[hi : hi + 2] in ("  ", "") for ln in body for _, hi in spans), "a cell runs into the next"
    return [[ln[lo:hi].strip() for lo, hi in spans] for ln in body]


@pytest.mark.parametrize(
    "estimator, lifting, limit",
    [("ls", "poly:3", None), ("bcls", "poly:3", "0 (= EDMD)"), ("ls", "rbf:6", "n/a")],
)
def test_nonlinear_sweep_table_is_aligned_and_says_n_a_where_no_limit_applies(capsys, estimator, lifting, limit):
    """Walkthrough repro: drifting columns and a bare "0" for BCLS's large-data limit."""
    code, out, err = _run(
        capsys, "sweep", "--system", "van-der-pol", "--estimator", estimator, "--lifting", lifting, *SMALL
    )
    assert code == 0, err
    cols = _columns(out)
    assert cols[0][:3] == ["b", "err_G (vs unquantized EDMD)", "large-data limit"]
    assert cols[0][-3:] == ["converged", "within radius", "settled offset med/max"]
    assert [c[0] for c in cols[1:]] == ["2", "4"] and all(
        c[-3].endswith("/2") and c[-2].endswith("/2") for c in cols[1:]
    )
    cells = [c[2] for c in cols[1:]]
    if limit is None:  # LS with a polynomial dictionary: the limit's number
        assert all(float(c) > 0 for c in cells)
    else:
        assert cells == [limit, limit]
    code, out, _ = _run(
        capsys, "sweep", "--system", "van-der-pol", "--estimator", estimator, "--lifting", lifting, *SMALL, "--json"
    )
    lims = [r["large_data"]["err_G"] for r in _strict(out)["results"]]
    # JSON: null where no limit applies, 0.0 where the limit is the unquantized EDMD itself
    expected = {"n/a": [None, None], "0 (= EDMD)": [0.0, 0.0]}.get(limit)
    assert lims == expected if expected is not None else all(v is not None and v > 0 for v in lims)


def test_nonlinear_defaults_apply_where_no_option_is_typed():
    from app.cli.main import build_parser
    from app.cli.study import koopman_config

    argv = ["sweep", "--system", "duffing"]
    args = build_parser("sweep").parse_args(argv)
    args.argv = tuple(argv)
    cfg = koopman_config(args)
    assert (cfg.trajectories, cfg.steps, cfg.realizations, cfg.bits) == (2000, 100, 20, tuple(range(2, 9)))
    assert (cfg.mpc.horizon, cfg.mpc.steps) == (20, 200)
    argv = ["sweep", "--system", "duffing", "--Q", "2,1", "--R", "0.5", "--horizon", "7"]
    args = build_parser("sweep").parse_args(argv)
    args.argv = tuple(argv)
    mpc = koopman_config(args).mpc
    assert (mpc.Q, mpc.R, mpc.horizon) == ((2.0, 1.0), (0.5,), 7)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["sweep", "--system", "van-der-pol", "--lifting", "poly:0"], "lifting 'poly:0': the degree"),
        (["sweep", "--system", "duffing", "--lifting", "rbf:0"], "K must be"),
        (["sweep", "--system", "dc-motor", "--lifting", "poly:2"], "only for a nonlinear --system"),
        (["sweep", "--system", "pendulum", "--trajectories", "1", "--steps", "3"], "samples: 3 samples"),
        (["sweep", "--system", "lorenz"], "unknown system"),
        (["sweep", "--system", "duffing", "--noise", "0.1"], "argument --noise: not available for a nonlinear"),
        (["sweep", "--system", "duffing", "--csv", "x.csv"], "argument --csv: not available for a nonlinear"),
    ],
)
def test_bad_nonlinear_input_is_one_line(capsys, argv, needle):
    code, out, err = _run(capsys, *argv)
    assert code == 2 and out == ""
    last = err.strip().splitlines()[-1]
    assert needle in last and "Traceback" not in err


def test_a_plant_file_with_a_vector_field_that_returns_nan_is_one_line(capsys, tmp_path, monkeypatch):
    mod = types.ModuleType("qsid_cli_nan_field")
    mod.f = lambda x, u: x * float("nan")  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "qsid_cli_nan_field", mod)
    p = tmp_path / "plant.toml"
    p.write_text('vector_field = "qsid_cli_nan_field:f"\nn = 2\nm = 1\n')
    code, _, err = _run(capsys, "sweep", "--system", str(p), *SMALL)
    assert code == 2 and "vector field of 'plant' returned NaN" in err.strip().splitlines()[-1]


def test_bits_for_a_nonlinear_plant_gives_b_observed_only(capsys):
    code, out, err = _run(capsys, "bits", "--system", "duffing", *SMALL, "--target", "0.5", "--json")
    assert code == 0, err
    d = _strict(out)
    assert d["b_robust"] is None and d["b_letter"] is None and "do not apply" in d["note"]
    fr = [r["stabilized_fraction"] for r in d["rows"]]
    ok = [f >= 0.5 for f in fr]
    want = next((d["rows"][i]["bits"] for i in range(len(ok)) if all(ok[i:])), None)
    assert d["b_observed"] == want


def test_a_plant_file_whose_module_sits_beside_it_runs_without_pythonpath(capsys, tmp_path):
    """Walkthrough repro: the module of a nonlinear plant file had to be on PYTHONPATH."""
    folder = tmp_path / "my plants"
    folder.mkdir()
    (folder / "qsid_cli_beside_field.py").write_text(
        "import numpy as np\n\n\ndef f(x, u):\n    return np.stack([x[:, 1], u[:, 0] - x[:, 0] - x[:, 1]], axis=1)\n"
    )
    plant = folder / "plant.toml"
    plant.write_text('vector_field = "qsid_cli_beside_field:f"\nn = 2\nm = 1\nx0 = [1.0, 0.0]\n')
    assert str(folder) not in sys.path and "qsid_cli_beside_field" not in sys.modules
    code, out, err = _run(capsys, "sweep", "--system", str(plant), *SMALL, "--json")
    assert code == 0, err
    assert _strict(out)["system"] == "plant" and str(folder) not in sys.path
