"""Engine bad input is always the engine's own error class (QsidError, a ValueError), never a raw numpy one."""

from __future__ import annotations

import numpy as np
import pytest

from qsid_core.control.mpc import MPCConfig
from qsid_core.errors import ConfigError, IdentificationError, QsidError
from qsid_core.identification.identify import identify
from qsid_core.quantization.moments import Moments


def test_mpc_without_an_input_box_is_a_config_error():
    with pytest.raises(ConfigError, match="u_max"):
        MPCConfig(u_max=None)


@pytest.mark.parametrize("estimator", ["ls", "bcls"])
@pytest.mark.parametrize(
    "bad",
    [
        dict(PP=np.array([["a", "b", "c"]] * 3, dtype=object)),
        dict(eps=np.array([])),
        dict(XP=np.ones((3, 3))),
        dict(PP=np.ones((3, 2))),
        dict(T=0),
    ],
    ids=["object-strings", "eps-empty", "XP-square", "PP-not-square", "T-zero"],
)
def test_malformed_moments_raise_identification_error(bad, estimator):
    good = dict(PP=np.eye(3) * 100.0, XP=np.ones((2, 3)), T=10, eps=np.full(3, 0.1))
    with pytest.raises(IdentificationError):
        identify(Moments(**{**good, **bad}), estimator)


def test_object_dtype_numbers_are_read_as_numbers():
    m = Moments(PP=(np.eye(3) * 100.0).astype(object), XP=np.ones((2, 3), dtype=object), T=10, eps=np.full(3, 0.1))
    ident = identify(m, "bcls")
    assert ident.A.shape == (2, 2) and np.all(np.isfinite(ident.A))
    assert issubclass(IdentificationError, QsidError)
