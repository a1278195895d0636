"""Issue 11's command-line repros: every bad input is one line and exit code 2; outputs are checked before
the run, inputs are never overwritten, existing outputs are replaced with a note (files) or need --force
(directories), --workers is capped to the CPU count."""

import importlib.util
import json
import os

import pytest

from app.cli import main

TINY = ["--trajectories", "3", "--steps", "50", "--realizations", "2", "--bits", "2"]
BIG = "1" + "0" * 400  # a JSON integer too large for a float


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def _one_line(code, out, err, needle=""):
    assert code == 2, err
    assert out == ""
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: "), err
    assert "Traceback" not in err and needle in err, err


SYSTEM_FILES = {
    "bigA.json": '{"A": [[' + BIG + ']], "B": [[1]]}',
    "bigx0.json": '{"A": [[0.5]], "B": [[1]], "x0": [' + BIG + "]}",
    "dateQ.toml": "A = [[0.5]]\nB = [[1.0]]\nQ = 1979-05-27\n",
    "objQ.json": json.dumps({"A": [[0.5]], "B": [[1.0]], "Q": {"a": 1}}),
    "objx0.json": json.dumps({"A": [[0.5]], "B": [[1.0]], "x0": {"a": 1}}),
    "dtnan.toml": "A = [[0.5]]\nB = [[1.0]]\ndt = nan\n",
    "dtneg.json": json.dumps({"A": [[0.5]], "B": [[1.0]], "dt": -5}),
}


@pytest.mark.parametrize("name", sorted(SYSTEM_FILES))
def test_bad_system_file_is_one_line(capsys, tmp_path, name):
    f = tmp_path / name
    f.write_text(SYSTEM_FILES[name])
    _one_line(*_run(capsys, "sweep", "--system", str(f), *TINY, "-q"))


@pytest.mark.skipif(
    importlib.util.find_spec("qsid_core.validate") is None,
    reason="needs the engine's input validation (qsid_core.validate, branch 'inputs')",
)
def test_boolean_matrix_entry_is_refused(capsys, tmp_path):
    f = tmp_path / "true.json"
    f.write_text(json.dumps({"A": [[True]], "B": [[1.0]]}))
    _one_line(*_run(capsys, "sweep", "--system", str(f), *TINY, "-q"))


def test_huge_rho_is_refused_before_the_run(capsys):
    _one_line(*_run(capsys, "sweep", *TINY, "--rho", "1e300"), "--rho")


def test_system_directory_says_directory(capsys, tmp_path):
    _one_line(*_run(capsys, "sweep", "--system", str(tmp_path), *TINY), "is a directory")


def test_empty_out_is_refused(capsys):
    _one_line(*_run(capsys, "sweep", *TINY, "--out", ""), "give a file name")
    _one_line(*_run(capsys, "reproduce", *TINY, "--out", ""), "give a directory name")


def test_out_equal_to_the_system_file_is_refused_and_the_file_kept(capsys, tmp_path):
    f = tmp_path / "plant.toml"
    text = "A = [[0.5]]\nB = [[1.0]]\n"
    f.write_text(text)
    _one_line(*_run(capsys, "sweep", "--system", str(f), *TINY, "--out", str(f)), "input file")
    same = tmp_path / "." / "plant.toml"  # another spelling of the same file
    _one_line(*_run(capsys, "sweep", "--system", str(f), *TINY, "--out", str(same)), "input file")
    assert f.read_text() == text


def test_unwritable_out_fails_before_the_run(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code, out, err = _run(capsys, "sweep", *TINY, "--out", str(blocker / "sub" / "r.json"))
    _one_line(code, out, err, "not a directory")
    assert "quantize" not in err  # nothing ran


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_read_only_directory_fails_before_the_run(capsys, tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        _one_line(*_run(capsys, "sweep", *TINY, "--out", str(ro / "r.json")), "permission denied")
    finally:
        ro.chmod(0o700)


def test_existing_out_file_is_replaced_with_a_note(capsys, tmp_path):
    out_file = tmp_path / "r.json"
    out_file.write_text("old")
    code, out, err = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "--out", str(out_file))
    assert code == 0
    assert f"--out {out_file} exists; it will be replaced" in err
    assert err.index("will be replaced") < err.index("quantize")  # said before the run
    assert json.loads(out_file.read_text()) == json.loads(out)


def test_reproduce_refuses_a_non_empty_directory_without_force(capsys, tmp_path):
    d = tmp_path / "fig"
    d.mkdir()
    (d / "notes.txt").write_text("mine")
    argv = ["reproduce", "--system", "boeing747", "--out", str(d), *TINY]
    _one_line(*_run(capsys, *argv), "--force")
    code, _, err = _run(capsys, *argv, "--force", "-q")
    assert code == 0, err
    assert "will be replaced" in err and (d / "notes.txt").read_text() == "mine" and (d / "index.html").is_file()


def test_workers_capped_to_the_cpu_count(capsys):
    code, out, err = _run(capsys, "sweep", *TINY, "--no-mpc", "--json", "--workers", "256")
    assert code == 0, err
    cpus = os.cpu_count()
    assert f"--workers 256 capped to {cpus}" in err and f"{cpus} worker(s)" in err


def test_a_dead_worker_process_is_one_line_and_a_run_without_workers_never_loads_the_process_pool(capsys, monkeypatch):
    import subprocess
    import sys
    from concurrent.futures.process import BrokenProcessPool

    cli_main = sys.modules["app.cli.main"]  # the module (app.cli.main is also the name of its function)

    def broken(argv, rep):
        raise BrokenProcessPool("a child process terminated abruptly")

    monkeypatch.setattr(cli_main, "_dispatch", broken)
    code, out, err = _run(capsys, "sweep", *TINY)
    assert code == 1 and out == "" and "a worker process died" in err and "Traceback" not in err
    check = "import sys, app.cli.main; print('concurrent.futures.process' in sys.modules)"
    loaded = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "False"  # the process pool's module (and multiprocessing) only when a run uses them
