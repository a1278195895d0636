import os
import signal
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # the checkout's packages come first
    sys.path.insert(0, str(ROOT))
if str(ROOT / "tests") not in sys.path:  # the shared helpers (tests/support.py)
    sys.path.append(str(ROOT / "tests"))

from support import open_tab  # noqa: E402

# The processes the tests start and interrupt stand for a program run from a terminal, where Ctrl-C is SIGINT
# with its default action. A test run started in the background of a non-interactive shell (`cmd &`) inherits
# SIGINT *ignored*, and every child would inherit that too (an ignored signal survives exec, a handled one is
# reset to the default): the Ctrl-C tests would then watch a program that rightly ignores Ctrl-C.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """With QSID_REQUIRE_BROWSER=1 (set by .ci/run) a skipped browser test fails: it must really run."""
    outcome = yield
    rep = outcome.get_result()
    required = os.environ.get("QSID_REQUIRE_BROWSER") == "1" and item.get_closest_marker("browser")
    if required and rep.skipped and not hasattr(rep, "wasxfail"):  # an expected failure is not a skip
        rep.outcome = "failed"
        rep.longrepr = f"browser test skipped in CI (QSID_REQUIRE_BROWSER=1): {rep.longrepr}"


@pytest.fixture
def dashboard():
    """An in-process dashboard server on 127.0.0.1 (no process pool); stopped afterwards."""
    from app.dashboard import DashboardApp

    a = DashboardApp(host="127.0.0.1", port=0, workers=0)
    yield a
    a.stop()


@pytest.fixture
def tab(dashboard):
    """A connected tab of ``dashboard`` at a small data size, its first view drawn (support.open_tab)."""
    t = open_tab(dashboard)
    yield t
    t.close()


@pytest.fixture(scope="session")
def lessons_app():
    """One dashboard server (two worker processes, a 1 GiB result cache) for the browser walks through every
    lesson, test_dashboard_drawn_browser.py's and then test_dashboard_legibility.py's (one worker runs both: the
    browser group): the lessons are computed once, by the first walk, and drawn from the cache for the next."""
    from app.dashboard import DashboardApp

    a = DashboardApp(host="127.0.0.1", port=0, workers=2, cache_bytes=1024 * 2**20)
    # no tab is open between the walks (nor between the legibility walk's modes): the server must not give the
    # results back meanwhile, as it does 20 s after its last tab closed
    a.idle.delay = 3600.0
    yield a
    a.stop()


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(config, items):
    """Browser and cluster tests start real processes (Chromium, dask) and take seconds: slow too.

    For ``pytest -n 2 --dist loadgroup`` (pyproject's options) every test gets a group: the browser tests one
    for them all (one Chromium at a time, as on a person's machine), every other test its file's (a module's
    fixtures, e.g. a server it shares, are built once, in one worker).

    The groups are then put in the order the workers should take them (pyproject's ``--no-loadscope-reorder``
    keeps it): the browser group first, as it is the longest (one worker runs it from the start while the other
    goes through the rest), then the files with the most slow tests, then the rest, each in collection order.
    The order of the tests within a group is kept."""
    groups: dict[str, list] = {}
    for item in items:
        browser = item.get_closest_marker("browser")
        if browser or item.get_closest_marker("cluster"):
            item.add_marker(pytest.mark.slow)
        group = "browser" if browser else item.nodeid.split("::")[0]
        item.add_marker(pytest.mark.xdist_group(group))
        groups.setdefault(group, []).append(item)

    def first(group: str) -> tuple:
        slow = sum(1 for item in groups[group] if item.get_closest_marker("slow"))
        return (group != "browser", -slow)

    items[:] = [item for group in sorted(groups, key=first) for item in groups[group]]


def pytest_sessionfinish(session, exitstatus):
    """``QSID_FUZZ_REPORT=FILE``: what every fuzzed engine call gave, per entry point (support.fuzz_call)."""
    path = os.environ.get("QSID_FUZZ_REPORT")
    if path:
        from support import write_fuzz_report

        write_fuzz_report(path)
