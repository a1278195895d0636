"""``--save FILE``: a benchmark's printed output also written to a file, with a header saying where it ran.

The docs include these files verbatim (``docs/performance.rst``), so the numbers shown are the
numbers a run printed. The header names the command, the time (UTC), the CPU count, the load
average at the start and the code measured (``git describe`` of the checkout, or ``QSID_BENCH_CODE``).
"""

from __future__ import annotations

import contextlib
import datetime
import os
import platform
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HEADER = "# qsid benchmark output"


class _Both:
    def __init__(self, *streams):
        self.streams = streams

    def write(self, s):
        for st in self.streams:
            st.write(s)
        return len(s)

    def flush(self):
        for st in self.streams:
            st.flush()


def code_version() -> str:
    if os.environ.get("QSID_BENCH_CODE"):
        return os.environ["QSID_BENCH_CODE"]
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), "describe", "--always", "--dirty"], capture_output=True, text=True, timeout=10
        )
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


@contextlib.contextmanager
def saved(path: str | None, argv: list, name: str | None = None):
    """Print to stdout and, with ``path``, to that file too (header first; ``name``: the script)."""
    if not path:
        yield
        return
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        fh.write(
            f"{HEADER}: {' '.join([name or Path(sys.argv[0]).name] + list(argv))}\n"
            f"# {now} · {platform.machine()} · {os.cpu_count()} CPUs (shared) · load average at start "
            f"{os.getloadavg()[0]:.1f} · code {code_version()}\n"
        )
        old = sys.stdout
        sys.stdout = _Both(old, fh)
        try:
            yield
        finally:
            sys.stdout = old


def pop_save(argv: list) -> str | None:
    """Remove ``--save FILE`` (or ``--save=FILE``) from ``argv``; return FILE or None."""
    for k, a in enumerate(argv):
        if a == "--save" and k + 1 < len(argv):
            path = argv[k + 1]
            del argv[k : k + 2]
            return path
        if a.startswith("--save="):
            del argv[k]
            return a.split("=", 1)[1]
    return None


def run(main, argv):
    """``main(argv)`` with ``--save FILE`` handled (the rest of ``argv`` goes to ``main``)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    path = pop_save(argv)
    script = getattr(sys.modules.get(main.__module__), "__file__", None)
    with saved(path, argv, Path(script).name if script else None):
        return main(argv)
