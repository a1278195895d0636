"""app.figures.raw: the fast JSON the dashboard sends is the same figure as plotly's own ``to_json``."""

from __future__ import annotations

import base64
import json

import numpy as np
import plotly.graph_objects as go
import pytest

from app.dashboard.session import iter_frames
from app.figures import registry
from app.figures.raw import PLOT_CONFIG, Wire, to_json
from app.frames.cache import SharedCache
from app.frames.render import Renderer, Sent
from app.settings.values import Values


def _plain(obj):
    """plotly's JSON with its base64 typed arrays decoded to lists, floats rounded (repr differences), NaN as
    None (a typed array holds NaN where the strict JSON writes null: both a gap)."""
    if isinstance(obj, dict):
        if set(obj) >= {"dtype", "bdata"}:
            a = np.frombuffer(base64.b64decode(obj["bdata"]), dtype=np.dtype(obj["dtype"]))
            if "shape" in obj:
                a = a.reshape([int(k) for k in str(obj["shape"]).split(",")])
            return _plain(a.tolist())
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_plain(v) for v in obj]
    if isinstance(obj, float):
        return None if np.isnan(obj) else float(f"{obj:.12g}")
    return obj


@pytest.fixture(scope="module")
def frame():
    v = Values(trajectories=10, steps=100, realizations=4, mpc_steps=20)
    return list(iter_frames(v, SharedCache()))[-1]


@pytest.mark.parametrize("name", [v.name for v in registry.VIEWS])
def test_fast_json_is_plotlys_figure(frame, name):
    fig = next(v for v in registry.VIEWS if v.name == name).build(frame)
    fast = json.loads(to_json(fig))
    assert fast.pop("config") == PLOT_CONFIG  # plotly.js's options, added for every plot the dashboard sends
    assert _plain(fast) == _plain(json.loads(fig.to_json()))


def test_fast_json_is_strict_json_with_gaps():
    fig = go.Figure(go.Scatter(x=np.arange(4.0), y=np.array([1.0, np.nan, np.inf, -np.inf])))
    fig.add_trace(go.Scatter(x=np.arange(6.0)[::2], y=[np.float64(2.0), np.int64(3), None]))
    text = to_json(fig)
    out = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    assert out["data"][0]["y"] == [1.0, None, None, None]
    assert out["data"][1]["x"] == [0.0, 2.0, 4.0]  # a strided (non-contiguous) array
    assert out["data"][1]["y"] == [2.0, 3, None]


def test_wire_is_what_viser_needs_and_reads_like_the_figure(frame):
    fig = next(v for v in registry.VIEWS if v.name == "error").build(frame)
    w = Wire(fig)
    assert w.to_json() == to_json(fig)
    assert w.layout is fig.layout and len(w.data) == len(fig.data)
    out = Renderer().render(
        next(iter_frames(Values(trajectories=10, steps=100, realizations=4, mpc_steps=20), SharedCache()))
    )
    assert out.figures and all(isinstance(f, Sent) and isinstance(f.wire, Wire) for f in out.figures.values())
