"""The port asked for is checked before anything else (bound, or one line saying why not), and the dashboard never
moves to another port unless asked (``--port 0``, ``--next-free-port``)."""

from __future__ import annotations

import socket

import pytest

from app.dashboard import DashboardApp
from app.dashboard.options import check_address, read_options
from qsid_core import ConfigError, QsidError


@pytest.fixture
def taken():
    """A loopback port held by another listener (what another program would do)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        yield s.getsockname()[1]


def _free_after(port: int) -> int:
    """The first port after ``port`` that is free now."""
    for p in range(port + 1, port + 100):
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", p))
                return p
            except OSError:
                continue
    raise AssertionError("no free port")


def test_a_taken_port_is_one_line_naming_it(taken):
    with pytest.raises(ConfigError) as info:
        check_address("127.0.0.1", taken)
    text = str(info.value)
    assert text.startswith(f"--port {taken} on 127.0.0.1 is in use by another program") and "\n" not in text
    assert "--next-free-port" in text and "--port 0" in text


def test_the_port_is_checked_before_the_files(taken, tmp_path):
    """A bad --system file too: the port is said first (nothing else is read before it)."""
    bad = tmp_path / "plant.json"
    bad.write_text("{")
    with pytest.raises(QsidError, match=rf"^--port {taken} on 127.0.0.1 is in use"):
        read_options(["--port", str(taken), "--system", str(bad)])
    with pytest.raises(QsidError, match="cannot parse plant.json"):
        read_options(["--port", "0", "--system", str(bad)])


def test_next_free_port_takes_the_next_free_one_and_port_0_any(taken):
    assert check_address("127.0.0.1", taken, next_free=True) == (_free_after(taken), None)
    port, _ = check_address("127.0.0.1", 0)
    assert port == 0  # (the server asks the system for one)
    args, _settings, _warning = read_options(["--port", str(taken), "--next-free-port"])
    assert args.asked_port == taken and args.port == _free_after(taken)


def test_the_server_never_moves_to_another_port_unless_asked(taken):
    """viser moves to the next port when the one asked for is taken (a program took it since the check): refused."""
    with pytest.raises(ConfigError, match=rf"--port {taken} on 127.0.0.1 was taken by another program"):
        DashboardApp(port=taken, workers=0)
    app = DashboardApp(port=taken, workers=0, exact_port=False)  # --next-free-port: fine
    try:
        assert app.port > taken
    finally:
        app.stop()
