"""The ``--dask`` value read: a local cluster of N workers, or the address of a running scheduler."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass

from qsid_core import ConfigError

__all__ = ["DaskSpec", "parse_dask_spec", "MAX_LOCAL_WORKERS"]

MAX_LOCAL_WORKERS = 256
_FORMS = "use 'local', 'local:N' (N worker processes here) or 'tcp://HOST:PORT' (a running dask scheduler)"


@dataclass(frozen=True)
class DaskSpec:
    """A parsed ``--dask`` value: ``workers`` for a local cluster, else the scheduler ``address``."""

    address: str | None = None
    workers: int | None = None

    @property
    def local(self) -> bool:
        return self.address is None


def parse_dask_spec(spec: str) -> DaskSpec:
    """Parse ``'local'``, ``'local:N'`` or ``'tcp://HOST:PORT'``.

    Raises
    ------
    ConfigError
        For anything else (one line naming the accepted forms).
    """
    s = str(spec).strip()
    if s == "local":
        return DaskSpec(
            workers=max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))
        )
    m = re.fullmatch(r"local:(\S+)", s)
    if m:
        try:
            n = int(m.group(1))
        except ValueError:
            raise ConfigError(f"dask: worker count in {s!r} must be an integer; {_FORMS}") from None
        if not 1 <= n <= MAX_LOCAL_WORKERS:
            raise ConfigError(f"dask: local worker count must be between 1 and {MAX_LOCAL_WORKERS}; got {n}")
        return DaskSpec(workers=n)
    m = re.fullmatch(r"tcp://(\[[0-9a-fA-F:]+\]|[A-Za-z0-9.\-]+):(\d+)", s)
    if m:
        port = int(m.group(2))
        if not 1 <= port <= 65535:
            raise ConfigError(f"dask: port must be between 1 and 65535; got {port} in {s!r}")
        return DaskSpec(address=s)
    raise ConfigError(f"dask: cannot read {s!r}; {_FORMS}")
