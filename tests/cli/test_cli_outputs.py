"""Outputs go only to a regular file or a new name: a FIFO, a device, a socket or a link to one is refused with
one line naming the path and what it is, before the run, and is left as it was."""

import os
import socket
import stat

import pytest

from app.cli import main

TINY = ["--bits", "4", "--realizations", "2", "--trajectories", "5", "--steps", "20", "-q"]


def _refused(capsys, argv, path, kind):
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: "), err
    assert str(path) in err and kind in err, err


@pytest.mark.parametrize("flag", ["--out", "--csv"])
def test_a_fifo_is_refused_and_kept(capsys, tmp_path, flag):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    _refused(capsys, ["sweep", *TINY, flag, str(fifo)], fifo, "named pipe")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_link_to_a_fifo_is_refused_and_both_are_kept(capsys, tmp_path):
    fifo, link = tmp_path / "pipe", tmp_path / "out.json"
    os.mkfifo(fifo)
    link.symlink_to(fifo)
    _refused(capsys, ["bits", *TINY, "--out", str(link)], link, "named pipe")
    assert link.is_symlink() and stat.S_ISFIFO(os.stat(link).st_mode)


def test_a_socket_is_refused(capsys, tmp_path):
    path = tmp_path / "s"
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(path))
        _refused(capsys, ["sweep", *TINY, "--out", str(path)], path, "socket")
    assert stat.S_ISSOCK(os.lstat(path).st_mode)


def test_a_figure_to_a_fifo_is_refused(capsys, tmp_path):
    fifo = tmp_path / "fig.svg"
    os.mkfifo(fifo)
    _refused(capsys, ["sweep", *TINY, "--figure", str(fifo)], fifo, "named pipe")


def test_a_link_to_a_regular_file_is_written_through(capsys, tmp_path):
    real, link = tmp_path / "real.json", tmp_path / "link.json"
    real.write_text("old")
    link.symlink_to(real)
    assert main(["sweep", *TINY, "--out", str(link)]) == 0
    capsys.readouterr()
    assert link.is_symlink() and real.read_text().startswith("{")


#: A run that prints its stage lines (no -q): a refusal before it is the only line on stderr.
LOUD = ["--bits", "4", "--realizations", "2", "--trajectories", "5", "--steps", "20"]
COMMANDS = {
    "sweep": ["sweep", *LOUD],
    "bits": ["bits", *LOUD],
    "datalength": ["datalength", "--bits", "4", "--samples", "50,100", "--realizations", "2"],
    "koopman": ["sweep", "--system", "van-der-pol", *LOUD],
}


def _refused_before_the_run(capsys, argv, *words):
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (code, out)
    assert len(err.splitlines()) == 1 and err.startswith("qsid: error: argument --"), err  # no stage line ran
    for w in words:
        assert w in err, err
    return err


@pytest.mark.parametrize("command", COMMANDS)
def test_a_dangling_link_and_a_pseudo_file_system_are_refused_before_the_run(capsys, tmp_path, command):
    link = tmp_path / "out.json"
    link.symlink_to(tmp_path / "gone" / "real.json")
    _refused_before_the_run(capsys, [*COMMANDS[command], "--out", str(link)], str(link), "does not exist")
    assert link.is_symlink() and not (tmp_path / "gone").exists()
    _refused_before_the_run(capsys, [*COMMANDS[command], "--out", "/proc/qsid-out.json"], "'/proc'")
    _refused_before_the_run(capsys, [*COMMANDS[command], "--out", "/sys/qsid-out.json"], "'/sys'")


@pytest.mark.parametrize("existing", [False, True], ids=["new", "existing"])
def test_a_trailing_slash_names_a_folder_and_never_writes_a_file_of_that_name(capsys, tmp_path, existing):
    folder = tmp_path / "newdir"
    if existing:
        folder.mkdir()
    for flag in ("--out", "--csv", "--figure"):
        _refused_before_the_run(capsys, [*COMMANDS["sweep"], flag, f"{folder}/"], "a folder; give a file name")
    assert folder.is_dir() == existing and not folder.is_file() and list(tmp_path.iterdir()) == ([folder] * existing)


def test_stdout_into_a_pipe_is_refused_before_the_run():
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    r = subprocess.run(
        [sys.executable, "-m", "app.cli", *COMMANDS["sweep"], "--out", "/dev/stdout"],
        cwd=root,
        env=dict(os.environ, PYTHONPATH=str(root)),
        capture_output=True,  # stdout is a pipe
        text=True,
        timeout=300,
    )
    assert r.returncode == 2 and r.stdout == "", r.stdout
    assert r.stderr.count("\n") == 1 and "named pipe" in r.stderr and "will be replaced" not in r.stderr, r.stderr


def test_an_output_that_fails_late_is_kept_in_the_temporary_folder(capsys, tmp_path, monkeypatch):
    """The disk fills after the run: each output goes to a file in the temporary folder, one line says where,
    the others are still written, exit status 2."""
    import errno
    import re
    from pathlib import Path

    import qsid_core.studies as studies
    import qsid_core.studies.records as records

    real = studies.replace_atomically

    def full_disk(path, text):
        if Path(path).parent == tmp_path:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, text)

    monkeypatch.setattr(studies, "replace_atomically", full_disk)
    monkeypatch.setattr(records, "replace_atomically", full_disk)
    code = main(["sweep", *TINY, "--json", "--out", str(tmp_path / "r.json"), "--csv", str(tmp_path / "r.csv")])
    out, err = capsys.readouterr()
    assert code == 2 and list(tmp_path.iterdir()) == []
    kept = re.findall(
        r"cannot write (--\w+) '[^']+' \(No space left on device\); it was written to '([^']+)' instead", err
    )
    assert [flag for flag, _ in kept] == ["--csv", "--out"], err
    try:
        for flag, name in kept:
            text = Path(name).read_text()
            assert (
                text.startswith("system,bits,") if flag == "--csv" else text.strip() == out.strip()
            )  # --json: the same JSON
    finally:
        for _, name in kept:
            os.unlink(name)
