"""Checks of ``--host`` / ``--port`` before the server starts (one clear line instead of a hang).

The port asked for is bound here, on every address of ``--host``, before anything else runs: a port without
the right to bind it (below 1024 for a user), a port in use or an address that is not this machine's is one
line and exit status 2. The server never moves to another port unless asked (``--port 0``, ``--next-free-port``).
"""

from __future__ import annotations

import argparse
import errno
import ipaddress
import socket

from qsid_core import ConfigError

__all__ = ["NEXT_FREE_TRIES", "OneLineParser", "check_address", "port_number", "who_can_connect"]


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


#: Ports ``--next-free-port`` tries after the one asked for (then it gives up with one line).
NEXT_FREE_TRIES = 100


def _addresses(host: str) -> list[tuple[int, str]]:
    """(family, address) of every address ``host`` resolves to (what the server will listen on).

    Raises
    ------
    ConfigError
        ``host`` cannot be resolved.
    """
    try:
        infos = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError, OSError) as exc:
        raise ConfigError(f"--host {host!r} cannot be resolved ({exc})") from None
    return sorted({(int(i[0]), str(i[4][0])) for i in infos})


def _bind_error(family: int, addr: str, port: int) -> OSError | None:
    """Why a listening socket cannot be bound to ``addr``:``port`` now (None: it can), with the options the server's
    own socket will have (``SO_REUSEADDR`` as asyncio sets it; IPv6 only on an IPv6 address)."""
    try:
        with socket.socket(family, socket.SOCK_STREAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6:
                s.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            s.bind((addr, port))
            s.listen(1)
    except OSError as exc:
        return exc
    return None


def _port_refused(host: str, addr: str, port: int, exc: OSError) -> str:
    """The one line saying why ``port`` cannot be used on ``host`` (``addr``: the address that refused it)."""
    where = f"--port {port} on {host}" + (f" ({addr})" if addr != host else "")
    if exc.errno in (errno.EACCES, errno.EPERM):
        low = " (ports below 1024 need root or the CAP_NET_BIND_SERVICE capability)" if 0 < port < 1024 else ""
        return (
            f"{where}: permission denied{low}; use a port from 1024 up, e.g. --port 8080, or --port 0 for any free port"
        )
    if exc.errno == errno.EADDRINUSE:
        return (
            f"{where} is in use by another program; stop it, choose another --port, add --next-free-port to take "
            "the next free one, or use --port 0 for any free port"
        )
    return f"{where} cannot be used ({exc.strerror or exc})"


def check_address(host: str, port: int, next_free: bool = False) -> tuple[int, str | None]:
    """Resolve ``host`` and bind ``port`` on every address it names, before anything else starts.

    Returns the port to listen on (``port``; with ``next_free``, the first free one after a taken ``port``) and a
    warning if ``host`` reaches beyond this machine.

    Raises
    ------
    ConfigError
        ``host`` cannot be resolved or is not an address of this machine, or ``port`` cannot be bound (no
        permission, in use, ...): one line naming the option and what to do.
    """
    addrs = _addresses(host)
    for family, addr in addrs:  # is the address ours? (any free port: the port is checked below)
        exc = _bind_error(family, addr, 0)
        if exc is not None:
            raise ConfigError(
                f"--host {host!r} ({addr}) is not an address of this machine ({exc.strerror or exc})"
            ) from None
    tries = NEXT_FREE_TRIES + 1 if next_free and port != 0 else 1
    candidates = range(port, min(65536, port + tries))
    for candidate in candidates:
        refused = next(((a, e) for f, a in addrs if (e := _bind_error(f, a, candidate)) is not None), None)
        if refused is None:
            break
        if refused[1].errno != errno.EADDRINUSE or len(candidates) == 1:  # another port would not help
            raise ConfigError(_port_refused(host, refused[0], candidate, refused[1]))
    else:
        raise ConfigError(
            f"--port {port} and the {len(candidates) - 1} ports after it on {host} are in use (--next-free-port); "
            "choose another --port, or use --port 0 for any free port"
        )
    ips = [ipaddress.ip_address(a.split("%")[0]) for _, a in addrs]
    if all(ip.is_loopback for ip in ips):
        return candidate, None
    return candidate, (
        f"warning: listening on {host} ({', '.join(a for _, a in addrs)}), not only on this machine: anyone who "
        "can reach it on the network can use the dashboard and its CPU (there is no login). Use --host "
        "127.0.0.1 to keep it private."
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
