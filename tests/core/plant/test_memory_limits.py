"""The size check refuses work that an address-space limit (ulimit -v) or a cgroup's memory cap would stop with a
raw MemoryError, not only work beyond the machine's free memory."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from qsid_core.plant.memory import cgroup_headroom, check_memory, memory_headroom

ROOT = Path(__file__).resolve().parents[3]

#: simulate() of 20,000 x 3,000 steps of the DC motor: 3.6 GiB of arrays, below this machine's free memory
#: but far beyond an address space of 1.5 GiB more than the interpreter holds already.
UNDER_LIMIT = """
import resource, sys
from qsid_core import dc_motor, simulate
used = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmSize:"))
resource.setrlimit(resource.RLIMIT_AS, (used + 1536 * 2**20, resource.RLIM_INFINITY))
try:
    simulate(dc_motor(), 20000, 3000)
except MemoryError:
    print("raw MemoryError")
except ValueError as exc:
    print(type(exc).__name__, exc)
"""


@pytest.mark.slow  # a subprocess importing the engine
def test_simulate_under_an_address_space_limit_is_one_engine_error():
    r = subprocess.run([sys.executable, "-c", UNDER_LIMIT], cwd=ROOT, capture_output=True, text=True, timeout=600)
    out = r.stdout.strip()
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert out.startswith("ConfigError simulate(20000 trajectories x 3000 steps) would need"), out
    assert "ulimit -v" in out and len(out.splitlines()) == 1


def _cgroup(tmp_path: Path, own: str, files: dict[str, str]) -> Path:
    (tmp_path / "self").write_text(own)
    for rel, text in files.items():
        f = tmp_path / "fs" / rel
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    return tmp_path / "fs"


def test_cgroup_v2_cap_and_its_ancestors(tmp_path):
    fs = _cgroup(
        tmp_path,
        "0::/box/app\n",
        {
            "box/app/memory.max": "max\n",  # no cap of its own ...
            "box/app/memory.current": "100\n",
            "box/memory.max": str(3 * 2**30),  # ... its container's applies
            "box/memory.current": str(2**30),
        },
    )
    assert cgroup_headroom(fs, tmp_path / "self") == 2 * 2**30


def test_cgroup_v1_cap_and_no_cap(tmp_path):
    fs = _cgroup(
        tmp_path,
        "4:memory:/job\n3:cpu:/job\n",
        {"memory/job/memory.limit_in_bytes": "1000000", "memory/job/memory.usage_in_bytes": "400000"},
    )
    assert cgroup_headroom(fs, tmp_path / "self") == 600000
    unlimited = _cgroup(tmp_path, "4:memory:/\n", {"memory/memory.limit_in_bytes": "9223372036854771712"})
    assert cgroup_headroom(unlimited, tmp_path / "self") is None
    assert cgroup_headroom(tmp_path / "none", tmp_path / "missing") is None


def test_check_memory_names_the_bound_that_refuses():
    room, why = memory_headroom()
    assert room is not None and room > 0 and why
    check_memory("small", 1024.0, "fine")
    with pytest.raises(ValueError, match=r"would need .* GiB .*more than this process can get now") as info:
        check_memory("huge", 4.0 * room, "use less")
    assert why in str(info.value) and str(info.value).endswith("use less")
