"""Panel values over the websocket are checked as strictly as the CLI checks them (no silent truncation)."""

import pytest

from app.dashboard.controls import CONTROLS
from app.dashboard.inputs import check_value
from app.dashboard.settings import InputError

BY_NAME = {c.name: c for c in CONTROLS}


@pytest.mark.parametrize("name,value", [("bits", 3.7), ("bits", "4"), ("bits", True)]
                         + [(c.name, v) for c in CONTROLS if c.kind == "checkbox" for v in ("yes", 1)])
def test_a_non_integer_word_length_and_a_non_boolean_checkbox_are_refused(name, value):
    with pytest.raises(InputError, match=BY_NAME[name].label.split()[0]):
        check_value(BY_NAME[name], value)


def test_a_whole_word_length_is_accepted():
    check_value(BY_NAME["bits"], 4)
    check_value(BY_NAME["bits"], 4.0)
