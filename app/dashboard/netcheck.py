"""Checks of ``--host`` / ``--port`` before the server starts (one clear line instead of a hang)."""

from __future__ import annotations

import argparse
import ipaddress
import socket

from qsid_core import ConfigError

__all__ = ["OneLineParser", "check_address", "port_number", "who_can_connect"]


class OneLineParser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (and exit status 2), not the usage block."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def port_number(text: str) -> int:
    """argparse type of ``--port``: 0 (any free port) .. 65535."""
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number; got {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"must be between 0 and 65535 (0: any free port); got {port}")
    return port


def check_address(host: str, port: int) -> str | None:
    """Resolve ``host`` and try to bind it; returns a warning if it reaches beyond this machine.

    Raises
    ------
    ConfigError
        ``host`` cannot be resolved or is not an address of this machine.
    """
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError, OSError) as exc:
        raise ConfigError(f"--host {host!r} cannot be resolved ({exc})") from None
    addrs = sorted({str(i[4][0]) for i in infos})
    for family, _, _, _, sockaddr in infos[:1]:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            try:
                s.bind((sockaddr[0], 0))  # any free port: only whether the address is ours is checked here
            except OSError as exc:
                raise ConfigError(
                    f"--host {host!r} ({sockaddr[0]}) is not an address of this machine ({exc.strerror or exc})"
                ) from None
    if all(ipaddress.ip_address(a.split("%")[0]).is_loopback for a in addrs):
        return None
    return (
        f"warning: listening on {host} ({', '.join(addrs)}), not only on this machine: anyone who can reach "
        "it on the network can use the dashboard and its CPU (there is no login). Use --host 127.0.0.1 "
        "to keep it private."
    )


def _own_addresses() -> list[str]:
    """This machine's non-loopback IPv4 addresses (its host name's, and the one its default route uses)."""
    found: set[str] = set()
    try:
        found |= {str(i[4][0]) for i in socket.getaddrinfo(socket.gethostname(), None, socket.AF_INET)}
    except (socket.gaierror, UnicodeError, OSError):
        pass
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("192.0.2.1", 9))  # TEST-NET-1: picks the outgoing address, sends nothing
            found.add(s.getsockname()[0])
    except OSError:
        pass
    return sorted(a for a in found if not ipaddress.ip_address(a).is_loopback)


def who_can_connect(host: str, port: int) -> str | None:
    """One note line for a server on ``host``:``port`` that others can reach (None: this machine only)."""
    try:
        addrs = sorted({str(i[4][0]) for i in socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)})
    except (socket.gaierror, UnicodeError, OSError):
        return None
    ips = [ipaddress.ip_address(a.split("%")[0]) for a in addrs]
    if all(ip.is_loopback for ip in ips):
        return None
    if any(ip.is_unspecified for ip in ips):
        urls = [f"http://{a}:{port}" for a in _own_addresses()] or [f"http://<this machine's address>:{port}"]
        where = "every network of this machine"
    else:
        urls = [f"http://{host}:{port}"]
        where = f"the network of {host}"
    return (
        f"note: others connect at {', '.join(urls)} (anyone who can reach {where}; no login; "
        "--max-tabs N limits how many tabs it serves)"
    )
