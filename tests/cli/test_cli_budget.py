"""``qsid budget``: per word length the runs a budget of bits buys and the model error, checked against an
independent computation of the same definition (plain numpy: simulate, dither-quantize, BCLS); the knee; the
table; bad input as one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.cli import main
from qsid_core import get_system

SCALE = ["--system", "boeing747", "--total-bits", "2e6", "--steps", "100", "--noise", "0.1", "--noise-known"]
BITS = (2, 4, 5, 6, 7, 8, 12, 16)


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _independent(total_bits: float, steps: int, bits: int, sigma: float, realizations: int, seed: int) -> list[float]:
    """err_G of BCLS at ``bits`` for a budget of ``total_bits``, by the definition alone: runs of ``steps``
    samples from x0 ~ U[-1, 1]^n with u ~ U[-1, 1]^m, Gaussian sensor noise on the states, every channel
    quantized with subtractive dither over its data range widened by half a cell on each side, BCLS with the
    quantization and noise variances subtracted."""
    s = get_system("boeing747")
    A, B, n, m = s.A, s.B, s.n, s.m
    G = np.hstack([A, B])
    runs = int(total_bits // (steps * (n + m) * bits))
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(realizations):
        u = rng.uniform(-1, 1, (runs, steps, m))
        x = np.empty((runs, steps + 1, n))
        x[:, 0] = rng.uniform(-1, 1, (runs, n))
        for t in range(steps):
            x[:, t + 1] = x[:, t] @ A.T + u[:, t] @ B.T
        x = x + sigma * rng.standard_normal(x.shape)  # the recorded states
        rec = [x.reshape(-1, n), u.reshape(-1, m)]
        q = []
        for sig in rec:
            lo, hi = sig.min(axis=0), sig.max(axis=0)
            eps = (hi - lo) / (2**bits - 1)  # 2^b cells over [lo - eps/2, hi + eps/2]
            lo_q = lo - eps / 2
            w = rng.uniform(-0.5, 0.5, sig.shape) * eps
            k = np.clip(np.floor((sig + w - lo_q) / eps), 0, 2**bits - 1)
            q.append((lo_q + (k + 0.5) * eps - w, eps))
        xq = q[0][0].reshape(runs, steps + 1, n)
        uq = q[1][0].reshape(runs, steps, m)
        psi = np.concatenate([xq[:, :-1], uq], axis=2).reshape(-1, n + m)
        xp = xq[:, 1:].reshape(-1, n)
        T = psi.shape[0]
        D = np.concatenate([q[0][1] ** 2 / 12 + sigma**2, q[1][1] ** 2 / 12])
        Gh = np.linalg.solve(psi.T @ psi - T * np.diag(D), psi.T @ xp).T
        out.append(float(np.linalg.norm(Gh - G) / np.linalg.norm(G)))
    return out


def _knee(errs: dict[int, float]) -> int:
    best = min(errs.values())
    return min(b for b, e in errs.items() if e <= 1.25 * best)


@pytest.mark.slow
def test_errors_and_knee_agree_with_an_independent_computation(capsys):
    R = 12
    code, out, err = _run(
        capsys, "budget", *SCALE, "--bits", ",".join(map(str, BITS)), "--estimator", "bcls", "--realizations",
        str(R), "--no-mpc", "--json",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    rows = {r["bits"]: r for r in d["rows"]}
    mine = {b: float(np.mean(_independent(2e6, 100, b, 0.1, R, 100 + b))) for b in BITS}
    for b in BITS:
        assert rows[b]["trajectories"] == int(2e6 // (100 * 6 * b))
        assert rows[b]["err_G"]["mean"] == pytest.approx(mine[b], rel=0.3), (b, rows[b]["err_G"], mine[b])
        assert rows[b]["err_G"]["std"] > 0
    assert abs(d["b_knee"] - _knee(mine)) <= 1
    assert d["b_best"] == min(rows, key=lambda b: rows[b]["err_G"]["mean"])


def test_noiseless_the_knee_is_at_the_top_of_the_range(capsys):
    code, out, err = _run(
        capsys, "budget", "--system", "boeing747", "--total-bits", "1e6", "--steps", "100", "--bits", "4,8,12,16",
        "--estimator", "bcls", "--realizations", "3", "--no-mpc", "--json", "-q",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    assert d["b_knee"] == d["b_best"] == 16 and err == ""
    assert [r["trajectories"] for r in d["rows"]] == [416, 208, 138, 104]


def test_the_table_is_aligned_and_names_the_word_lengths(capsys):
    code, out, err = _run(
        capsys, "budget", "--system", "boeing747", "--total-bits", "2400", "--steps", "100", "--bits", "1:5",
        "--realizations", "2", "--mpc-steps", "20",
    )  # fmt: skip
    assert code == 0, err
    lines = out.splitlines()
    head, rule = lines[1], lines[2]
    assert head.split()[:3] == ["b", "runs", "samples"] and "stabilized" in head and "cost gap" in head
    assert len(head) == len(rule) and set(rule) == {"-", " "}
    table = lines[3:8]
    assert [ln.split()[0] for ln in table] == ["1", "2", "3", "4", "5"]
    assert "not identifiable" in table[4]  # 2400 bits buy no run at b = 5
    assert all(len(ln) <= len(head) for ln in table)
    assert "b = 5: the budget buys no run" in out and "b_best = " in out and "b_knee = " in out and "b_loop = " in out
    assert "budget of 2400 bits: b = 1: 4 runs" in err


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--total-bits", "-1"], "argument --total-bits: must be >= 0"),
        (["--total-bits", "0"], "total bits must be in [1, 1e+15]; got 0"),
        (["--total-bits", "lots"], "argument --total-bits: must be a number"),
        (["--total-bits", "100"], "total bits: 100 bits identify nothing at any b"),
        (["--total-bits", "1e6", "--steps", "0"], "argument --steps: must be positive"),
        (["--total-bits", "1e6", "--steps", "1.5"], "argument --steps: must be an integer"),
        (["--total-bits", "1e6", "--trajectories", "5"], "argument --trajectories: the budget sets the runs"),
        (["--total-bits", "1e6", "--input-bits", "exact"], "input bits / state bits"),
        ([], "the following arguments are required: --total-bits"),
    ],
)
def test_bad_input_is_one_line(capsys, argv, message):
    code, out, err = _run(capsys, "budget", "--system", "boeing747", *argv)
    assert code == 2 and out == ""
    assert err.startswith("qsid: error: ") and message in err and len(err.strip().splitlines()) == 1


def test_a_nonlinear_plant_shows_its_loops_settled_offsets(capsys):
    code, out, err = _run(
        capsys, "budget", "--system", "pendulum", "--lifting", "poly:3", "--estimator", "bcls", "--total-bits", "3e5",
        "--steps", "50", "--bits", "2,6", "--realizations", "2", "--mpc-steps", "60", "-q",
    )  # fmt: skip
    assert code == 0, err
    head = out.splitlines()[1]
    assert "within radius" in head and "settled offset med/max" in head and "cost gap" not in head
    assert "lifting poly:3" in out.splitlines()[0] and "predicted" not in head
    rows = out.splitlines()[3:5]
    assert [r.split()[:2] for r in rows] == [["2", "1000"], ["6", "333"]]


def test_bits_per_sample_proposes_a_split_and_measures_it_against_the_uniform_one(capsys):
    code, out, err = _run(
        capsys, "budget", "--system", "dc-motor", "--total-bits", "2e6", "--steps", "100", "--estimator", "bcls",
        "--realizations", "4", "--bits-per-sample", "24", "--json", "-q",
    )  # fmt: skip
    assert code == 0, err
    d = json.loads(out)
    assert d["kind"] == "budget-allocation" and d["config"]["bits_per_sample"] == 24
    assert d["trajectories"] == 2_000_000 // (100 * 24) and len(d["channels"]) == 5
    assert d["uniform"]["bits"] == [5, 5, 5, 5, 4] and sum(d["proposed"]["bits"]) == 24
    assert d["proposed"]["err_G"]["mean"] < d["uniform"]["err_G"]["mean"]
    code, out, err = _run(
        capsys, "budget", "--system", "dc-motor", "--total-bits", "2e6", "--steps", "100", "--realizations", "2",
        "--bits-per-sample", "24",
    )  # fmt: skip
    lines = out.splitlines()
    assert lines[1].split()[0] == "split" and [ln.split()[0] for ln in lines[3:5]] == ["uniform", "proposed"]
    assert len(lines[1]) == len(lines[2]) and "the proposal lower in" in lines[5]


@pytest.mark.parametrize(
    "argv,message",
    [
        (["--bits-per-sample", "2"], "bits per sample must be between 6 and 192; got 2"),
        (["--bits-per-sample", "x"], "argument --bits-per-sample: must be an integer"),
        (["--bits-per-sample", "24", "--bits", "4"], "argument --bits-per-sample: the split is of B bits per sample"),
        (
            ["--bits-per-sample", "24", "--dither", "none"],
            "bits per sample: the allocation's error model is for linear",
        ),
    ],
)
def test_bits_per_sample_bad_input_is_one_line(capsys, argv, message):
    code, out, err = _run(capsys, "budget", "--system", "boeing747", "--total-bits", "1e6", *argv)
    assert code == 2 and out == "" and message in err and len(err.strip().splitlines()) == 1, err
