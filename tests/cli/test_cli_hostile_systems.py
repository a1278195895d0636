"""A hostile ``--system`` file (nested 1,000 deep, a huge number, binary, a FIFO, a directory, a loop of links ...)
is one line from ``qsid sweep`` (exit status 2) and from the dashboard's start-up, the same line the engine gives
(``tests/core/plant/test_hostile_plant_files.py``)."""

from __future__ import annotations

import pytest
from support import HOSTILE_PLANT_FILES, hostile_plant_file

from app.cli import main as cli_main
from qsid_core import QsidError


@pytest.mark.parametrize("case", HOSTILE_PLANT_FILES)
def test_the_cli_and_the_dashboard_refuse_it_with_the_same_line(tmp_path, capsys, case):
    from app.dashboard.options import read_options

    path, words = hostile_plant_file(tmp_path, case)
    assert cli_main(["sweep", "--system", str(path), "--bits", "4", "-q"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and err.startswith("qsid: error: ") and words in err, err
    with pytest.raises(QsidError) as info:
        read_options(["--system", str(path), "--port", "0"])
    assert "\n" not in str(info.value) and words in str(info.value)
    if case != "list.json":  # (the dashboard's panel checks a linear plant's keys itself)
        assert err.removeprefix("qsid: error: ").strip() in str(info.value)
