"""qsid_core.studies.outputs: a file is written whole, only over a regular file or a new name."""

import os
import stat

import pytest

from qsid_core.errors import OutputPathError, QsidError
from qsid_core.studies import output_target, replace_atomically


def test_a_new_name_and_a_regular_file_are_written(tmp_path):
    new = tmp_path / "new.txt"
    replace_atomically(new, "a")
    assert new.read_text() == "a"
    new.chmod(0o600)
    replace_atomically(new, "b")
    assert new.read_text() == "b" and stat.S_IMODE(os.stat(new).st_mode) == 0o600
    assert [p.name for p in tmp_path.iterdir()] == ["new.txt"]  # no temporary file left


def test_a_fifo_is_refused_with_the_engine_error_naming_it(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(OutputPathError, match="named pipe") as exc:
        replace_atomically(fifo, "x")
    assert isinstance(exc.value, QsidError) and str(fifo) in str(exc.value)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pipe"]


def test_a_directory_is_refused(tmp_path):
    with pytest.raises(OutputPathError, match="a directory"):
        output_target(tmp_path)


def test_a_link_resolves_to_its_file_and_stays_a_link(tmp_path):
    real, link = tmp_path / "real.txt", tmp_path / "link.txt"
    real.write_text("old")
    link.symlink_to(real)
    assert output_target(link) == real.resolve()
    replace_atomically(link, "new")
    assert link.is_symlink() and real.read_text() == "new"


def test_a_dangling_link_writes_its_target(tmp_path):
    link = tmp_path / "link.txt"
    link.symlink_to(tmp_path / "later.txt")
    replace_atomically(link, "x")
    assert (tmp_path / "later.txt").read_text() == "x" and link.is_symlink()
