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
