import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """With QSID_REQUIRE_BROWSER=1 (set by .ci/run) a skipped browser test fails: it must really run."""
    outcome = yield
    rep = outcome.get_result()
    if os.environ.get("QSID_REQUIRE_BROWSER") == "1" and item.get_closest_marker("browser") and rep.skipped:
        rep.outcome = "failed"
        rep.longrepr = f"browser test skipped in CI (QSID_REQUIRE_BROWSER=1): {rep.longrepr}"
