"""Panel values over the websocket are checked as strictly as the CLI checks them (no silent truncation)."""

import pytest

from app.dashboard.controls import CONTROLS
from app.dashboard.inputs import check_value
from app.dashboard.settings import InputError

BY_NAME = {c.name: c for c in CONTROLS}


@pytest.mark.parametrize(
    "name,value",
    [("bits", 3.7), ("bits", "4"), ("bits", True)]
    + [(c.name, v) for c in CONTROLS if c.kind == "checkbox" for v in ("yes", 1)],
)
def test_a_non_integer_word_length_and_a_non_boolean_checkbox_are_refused(name, value):
    with pytest.raises(InputError, match=BY_NAME[name].label.split()[0]):
        check_value(BY_NAME[name], value)


def test_a_whole_word_length_is_accepted():
    check_value(BY_NAME["bits"], 4)
    check_value(BY_NAME["bits"], 4.0)


def _custom(a):
    from app.dashboard.settings import Values, resolve_system

    return resolve_system(Values(system="custom", a_text=a, b_text="0; 1"))


@pytest.mark.parametrize(
    "a,why",
    [
        ("\u0661 0; 0 0.5", "plain ASCII"),
        ("\u0967 0; 0 0.5", "plain ASCII"),
        ("1e-320 0; 0 0.5", "too close to zero"),
        ("1e-200 0; 0 0.5", "too close"),
    ],
)
def test_other_scripts_digits_and_tiny_entries_are_refused_with_one_clear_line(a, why):
    with pytest.raises(InputError, match=why) as exc:
        _custom(a)
    assert "\n" not in str(exc.value) and "DARE" not in str(exc.value)


def test_ordinary_and_zero_entries_pass():
    assert _custom("0.9 0.1; 0 0.8").system.A.tolist() == [[0.9, 0.1], [0.0, 0.8]]


@pytest.mark.parametrize("text", ["[1, 0]", "1, 0", "1 0", "[[1, 0]]", "1; 0"])
def test_x0_is_accepted_as_a_flat_list(text):
    from app.dashboard.settings import parse_vector

    assert parse_vector(text, "x0", 2) == (1.0, 0.0)
