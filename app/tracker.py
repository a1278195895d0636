"""multiprocessing's resource tracker, watched: if it dies, it is reaped and replaced quietly.

The resource tracker is a child process that CPython starts the first time a
program creates a named semaphore (every process pool does); it unlinks those the
program forgets. If it is killed, CPython notices only at the next semaphore, then
leaves it a zombie until then, warns, and starts a new tracker which prints a
``KeyError: '/mp-…'`` traceback for every semaphore released afterwards (they were
registered with the tracker that died).

:func:`check` (called every second by the dashboard's pool watchdog) reaps a dead
tracker at once (no zombie), says so in one line, and starts a new one running
:func:`main`: CPython's loop, except that releasing a name it never saw is ignored.
"""

from __future__ import annotations

import os
import signal
import sys
import warnings
from collections.abc import Callable
from multiprocessing import resource_tracker, spawn, util

__all__ = ["check", "main", "ensure_tolerant"]


def ensure_tolerant() -> bool:
    """Start this program's resource tracker now, running :func:`main`, unless one already runs; True if started.

    For a program about to start processes it may kill at any moment (a local dask cluster stopped by a
    signal during its start-up): a process killed between creating a semaphore and registering it makes
    CPython's tracker print a ``KeyError`` traceback when the name is released; :func:`main` ignores it.
    """
    rt = getattr(resource_tracker, "_resource_tracker", None)
    if rt is None:
        return False
    with rt._lock:
        if rt._pid is not None:
            return False
        _launch(rt)
    return True


def check(say: Callable[[str], None]) -> bool:
    """Replace this program's resource tracker if it died; True if it did. ``say`` gets the one line."""
    rt = getattr(resource_tracker, "_resource_tracker", None)
    pid = getattr(rt, "_pid", None)
    if rt is None or pid is None:
        return False
    with rt._lock:
        if rt._pid != pid:
            return False
        try:
            done, status = os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:  # not a child of ours any more: gone
            done, status = pid, 0
        if done == 0:
            return False
        os.close(rt._fd)
        rt._fd, rt._pid = None, None
        how = (
            f"signal {os.WTERMSIG(status)}" if os.WIFSIGNALED(status) else f"status {os.waitstatus_to_exitcode(status)}"
        )
        new = _launch(rt)
    say(f"multiprocessing's resource tracker (pid {pid}) ended ({how}); started a new one (pid {new})")
    return True


def _launch(rt) -> int:
    """Start :func:`main` as ``rt``'s tracker process (as CPython's ``ensure_running`` does); its pid."""
    r, w = os.pipe()
    try:
        fds = [r]
        try:
            fds.append(sys.stderr.fileno())
        except (AttributeError, OSError, ValueError):
            pass
        exe = spawn.get_executable()
        flags = util._args_from_interpreter_flags()  # type: ignore[attr-defined]  # CPython's private helper
        args = [exe, *flags, "-c", f"from app.tracker import main; main({r})"]
        blocked = {signal.SIGINT, signal.SIGTERM}
        old = signal.pthread_sigmask(signal.SIG_BLOCK, blocked)  # the child ignores them before it can be hit
        try:
            pid = util.spawnv_passfds(os.fsencode(exe), args, fds)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
    except BaseException:
        os.close(w)
        raise
    finally:
        os.close(r)
    rt._fd, rt._pid = w, pid
    return pid


def main(fd: int) -> None:
    """The replacement tracker: keep the names registered through pipe ``fd``; unlink those left at its end."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    funcs = resource_tracker._CLEANUP_FUNCS  # type: ignore[attr-defined]  # CPython's cleanup table
    cache: dict[str, set] = {rtype: set() for rtype in funcs}
    try:
        with open(fd, "rb") as f:
            for line in f:
                try:
                    cmd, name, rtype = line.strip().decode("ascii").split(":")
                except ValueError:
                    continue
                if rtype not in cache:
                    continue
                if cmd == "REGISTER":
                    cache[rtype].add(name)
                elif cmd == "UNREGISTER":  # a name of the tracker that died: nothing to do
                    cache[rtype].discard(name)
    finally:
        for rtype, names in cache.items():
            for name in names:
                try:
                    funcs[rtype](name)
                except Exception as exc:
                    warnings.warn(f"resource_tracker: {name!r}: {exc}", stacklevel=1)
