"""What followers cost the teacher's tab: the same changes timed with 0 and with N followers, side by side.

One dashboard server in this process (so that the teacher's session and its own timings can be read), with
the teacher's tab a websocket client at the bare address. N followers are N websockets at the teacher's
follow link, opened by a child process that reads (and drops) everything they are sent, so that their
reading does not share this interpreter. The teacher's tab makes the same changes in three blocks: without
followers, with N, without again (a block: ``--rounds`` times a word-length change, which only redraws
cached results, and a new data seed, which computes). Per kind of change it prints the median seconds from
the change to the teacher's last frame drawn, per block, and, with followers, how long after that every
follower showed it. Numbers are printed (``--save FILE`` writes them too), never asserted; the machine's
load average is in the header.

Usage::

    python benchmarks/bench_follow.py [--followers 30] [--rounds 6] [--workers 2] [--save FILE]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for _p in (str(ROOT), str(HERE)):
    if _p not in sys.path:
        sys.path.insert(0, _p)
import msgspec  # noqa: E402
from _support import CAMERA, connect_ws  # noqa: E402
from _tee import saved  # noqa: E402

WAIT_S = 600.0  # one change may take this long before the benchmark gives up (a hang guard)


def _clients(url: str, n: int) -> None:
    """(the child process) ``n`` websockets at ``url`` reading everything, until stdin closes."""
    socks = [connect_ws(url, open_timeout=WAIT_S) for _ in range(n)]
    for ws in socks:
        ws.send(msgspec.msgpack.encode(CAMERA))
        threading.Thread(target=_read, args=(ws,), daemon=True).start()
    print("connected", flush=True)
    sys.stdin.read()
    for ws in socks:
        ws.close()


def _read(ws) -> None:
    try:
        while True:
            ws.recv()
    except Exception:  # closed
        pass


def _wait(what: str, done) -> None:
    end = time.monotonic() + WAIT_S
    while not done():
        if time.monotonic() > end:
            raise TimeoutError(what)
        time.sleep(0.005)


def _block(app, teacher, rounds: int, seed0: int, followers: list) -> dict:
    """Seconds per change (the teacher's, the followers' lag) for ``rounds`` word-length and seed changes."""
    out: dict = {"b": [], "seed": [], "b lag": [], "seed lag": []}
    cpu = _cpu()
    for r in range(rounds):
        for kind in ("b", "seed"):
            name, value = ("bits", 3 + (r % 2) * 6) if kind == "b" else ("data_seed", seed0 + r)
            t0 = time.perf_counter()
            teacher.controls[name].value = value
            assert teacher.wait_idle(WAIT_S), "the teacher's tab did not finish"
            t1 = time.perf_counter()
            out[kind].append(t1 - t0)
            if followers:
                last = teacher.last_frame
                _wait("the followers", lambda last=last: all(f.last_frame is last for f in followers))
                out[f"{kind} lag"].append(time.perf_counter() - t1)
    out["cpu"] = [(_cpu() - cpu) / rounds]
    return out


def _cpu() -> float:
    """CPU seconds of this process so far (the server and its tabs; not the pool's workers, not the clients)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--followers", type=int, default=30)
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--save", default=None)
    ap.add_argument("--clients", nargs=2, metavar=("URL", "N"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.clients:
        _clients(args.clients[0], int(args.clients[1]))
        return 0
    from app.dashboard import DashboardApp

    app = DashboardApp(host="127.0.0.1", port=0, workers=args.workers)
    ws = connect_ws(app.url, open_timeout=WAIT_S)  # the teacher's tab
    threading.Thread(target=_read, args=(ws,), daemon=True).start()
    ws.send(msgspec.msgpack.encode(CAMERA))
    try:
        with saved(args.save, sys.argv, "bench_follow.py"):
            _measure(app, args)
    finally:
        ws.close()
        app.stop()
    return 0


def _measure(app, args) -> None:
    """The three blocks (see the module docstring), printed."""
    child = None
    try:
        (teacher,) = app.wait_for_sessions(1, timeout=WAIT_S)
        assert teacher.wait_idle(WAIT_S)
        code = teacher.codes.view.code
        print(f"teacher's tab: view {code}, {app.workers} pool workers, {args.rounds} rounds per block")
        _block(app, teacher, 2, 100, [])  # every word length and the first seeds cached once
        blocks = {"0 followers (before)": _block(app, teacher, args.rounds, 200, [])}
        child = subprocess.Popen(
            [sys.executable, __file__, "--clients", f"{app.url}/f/{code}", str(args.followers)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=ROOT,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
        )
        assert child.stdout is not None and child.stdout.readline().strip() == "connected"
        _wait("the followers", lambda: app.follow.followers(code) == args.followers)
        followers = [s for s in app.wait_for_sessions(args.followers + 1) if s is not teacher]
        _wait("the followers' first view", lambda: all(f.last_frame is teacher.last_frame for f in followers))
        blocks[f"{args.followers} followers"] = _block(app, teacher, args.rounds, 300, followers)
        assert all(f.timings == {} for f in followers), "a follower computed"
        assert child.stdin is not None
        child.stdin.close()
        child.wait(timeout=60)
        _wait("the followers leaving", lambda: app.follow.followers(code) == 0)
        blocks["0 followers (after)"] = _block(app, teacher, args.rounds, 400, [])
        print(
            f"{'block':<22} {'b change (s)':>13} {'seed change (s)':>16} {'b: followers +s':>16} "
            f"{'seed: +s':>9} {'server CPU s/round':>19}"
        )
        for name, d in blocks.items():
            med = {k: (f"{statistics.median(v):.3f}" if v else "-") for k, v in d.items()}
            print(
                f"{name:<22} {med['b']:>13} {med['seed']:>16} {med['b lag']:>16} {med['seed lag']:>9} {med['cpu']:>19}"
            )
        print(
            "(medians over the rounds; 'followers +s': from the teacher's last frame until every follower "
            "showed it;\n server CPU: this process's CPU seconds per round of one b and one seed change, "
            "the pool's workers not counted)"
        )
    finally:
        if child is not None and child.poll() is None:
            child.kill()
            child.wait()


if __name__ == "__main__":
    sys.exit(main())
