"""The constraints of the letter's problem (2) from the CLI and the dashboard: terminal weight Qf and terminal box."""

import numpy as np
import pytest

from app.cli import main
from app.settings.config import mpc_config
from app.settings.values import InputError, Values
from qsid_core.control.mpc import MPCConfig
from qsid_core.plant.systems import get_system
from qsid_core.studies.config import SweepConfig
from qsid_core.studies.experiment import Experiment

TINY = ["--bits", "6", "--realizations", "3", "--trajectories", "20", "--steps", "100", "-q", "--json"]


def _cfg(capsys, *extra):
    import json

    assert main(["sweep", *TINY, *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(
    "flag, want",
    [
        (["--Qf", "dare"], None),
        (["--Qf", "Q"], [1.0, 0.1, 0.1]),
        (["--Qf=2"], [2.0]),
        (["--Qf=1,2,3"], [1.0, 2.0, 3.0]),
    ],
)
def test_cli_terminal_weight(capsys, flag, want):
    from app.cli import build_parser
    from app.cli.parser import UsageError  # noqa: F401  (the parser is the CLI's)
    from app.cli.runner import config, system_from_args

    args = build_parser().parse_args(["sweep", *TINY, *flag])
    cfg = config(args, system_from_args(args), True)
    assert (None if cfg.mpc.Qf is None else list(cfg.mpc.Qf)) == want
    assert main(["sweep", *TINY, *flag]) == 0


def test_terminal_weight_changes_the_bound_and_terminal_box_binds():
    slow = SweepConfig(system="boeing747", bits=(6,), realizations=3, trajectories=20, steps=100)
    th_dare = Experiment(slow).theory(6)
    th_q = Experiment(SweepConfig(**{**slow.__dict__, "mpc": MPCConfig(Qf=(1.0, 0.1, 0.1, 0.1))})).theory(6)
    assert th_dare.delta != pytest.approx(th_q.delta, rel=1e-3)  # P: the Riccati recursion started at Qf
    free = Experiment(slow).closed_loops(6)
    boxed = Experiment(SweepConfig(**{**slow.__dict__, "mpc": MPCConfig(xf_max=0.1)})).closed_loops(6)
    assert boxed.qp_steps > free.qp_steps  # the terminal box is active: the QP solves it
    assert not np.allclose(np.nan_to_num(boxed.inputs), np.nan_to_num(free.inputs))


@pytest.mark.parametrize(
    "args, message",
    [
        (["--Qf", "abc"], "argument --Qf: must be 'dare', 'Q' or numbers"),
        (["--Qf=1,2"], "Qf must have 1 or 3 entries"),
        (["--Qf=-1"], "Qf diagonal must be >= 0"),
        (["--terminal-box=0"], "xf_max must be positive"),
        (["--terminal-box=1,2"], "xf_max must have 1 or 3 entries"),
    ],
)
def test_cli_terminal_bad_input_is_one_line(capsys, args, message):
    assert main(["sweep", *TINY, *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err


def test_dashboard_terminal_settings():
    s = get_system("dc-motor")
    assert mpc_config(Values(), s).Qf is None and mpc_config(Values(), s).xf_max is None
    m = mpc_config(Values(qf="Q", terminal_box="0.5"), s)
    assert m.Qf == (1.0, 0.1, 0.1) and m.xf_max == (0.5, 0.5, 0.5)
    assert mpc_config(Values(qf="DARE"), s).Qf is None
    for v, msg in (
        (Values(qf="x"), "Qf"),
        (Values(terminal_box="0"), "terminal box"),
        (Values(terminal_box="1, 2"), "terminal box"),
    ):
        with pytest.raises(InputError, match=msg):
            mpc_config(v, s)
