"""Panel values over the websocket are checked as strictly as the CLI checks them (no silent truncation)."""

import pytest

from app.dashboard.controls import CONTROLS
from app.dashboard.inputs import check_value
from app.settings.values import InputError

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
    from app.settings.values import Values, resolve_system

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
    from app.settings.values import parse_vector

    assert parse_vector(text, "x0", 2) == (1.0, 0.0)


# ----- values sent over the websocket, as a modified page would --------------------------------------------
def _send_raw(tab, handle, value) -> None:
    import msgspec

    tab.ws.send(
        msgspec.msgpack.encode({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": {"value": value}})
    )


SENT = [
    ("bits", 3.7, "needs a whole number"),  # viser alone ran it as b = 3
    ("bits", "5", "expected a whole number, got str"),  # ... as b = 5
    ("bits", True, "expected a whole number, got bool"),  # ... as b = 1
    ("trajectories", 20.5, "needs a whole number"),
    ("guard", "no", "expected on/off"),  # viser alone turned the guard band on
    ("guard", "false", "expected on/off"),
    ("guard", 1, "expected on/off"),
    ("guard", [0], "expected on/off"),
    ("guard", 0, "expected on/off"),  # ... or off
    ("noise_known", "", "expected on/off"),
    ("u_max", "2", "expected a number, got str"),
    ("dither", 3, "expected text"),
]


@pytest.mark.slow
def test_values_of_the_wrong_type_sent_over_the_websocket_are_refused_before_any_conversion(tab):
    from support import wait_until

    for name, value, words in SENT:
        handle = tab.controls[name]
        before, gen, frames = handle.value, tab.session.generation, tab.session.frames_drawn
        tab.controls.error.visible = False
        _send_raw(tab, handle, value)
        wait_until(lambda: tab.error is not None, f"{name} = {value!r} refused")
        err = tab.error
        assert words in err and "the value sent" in err and "keeps its last value" in err, (name, value, err)
        assert BY_NAME[name].label in err and "\n" not in err.split("  \n")[0]
        assert handle.value == before and type(handle.value) is type(before), (name, value, handle.value)
        assert tab.session.generation == gen and tab.session.frames_drawn == frames
    # a good value of the right type sent the same way still goes through, and clears that input's message; the
    # other refused inputs' messages stay until each of them is changed again
    refused = {BY_NAME[name].label for name, _, _ in SENT}
    for name, value in (("bits", 6), ("bits", 7.0), ("guard", False)):
        gen = tab.session.generation
        _send_raw(tab, tab.controls[name], value)
        wait_until(lambda: tab.session.generation > gen, f"{name} = {value!r} taken")
        tab.wait()
        refused.discard(BY_NAME[name].label)
        assert getattr(tab.frame.values, name) == value
        assert type(tab.controls[name].value) is BY_NAME[name].convert
        assert tab.error is not None and BY_NAME[name].label + ": the value sent" not in tab.error
        assert all(f"{label}: the value sent" in tab.error for label in refused), (refused, tab.error)
    for name in ("trajectories", "u_max", "noise_known", "dither"):  # each sent again, as it is: taken
        _send_raw(tab, tab.controls[name], tab.controls[name].value)
        label = BY_NAME[name].label
        wait_until(lambda: f"{label}: the value sent" not in (tab.error or ""), f"{label}'s refusal goes")
    assert tab.wait().error is None


@pytest.mark.parametrize(
    "name,value", [("bits", 3.7), ("bits", "5"), ("bits", True), ("guard", "false"), ("guard", [0])]
)
def test_check_sent_names_the_input_and_keeps_it(name, value):
    from types import SimpleNamespace

    from app.dashboard.inputs import check_sent

    handle = SimpleNamespace(label=BY_NAME[name].label)
    el = SimpleNamespace(inputs={name: handle}, q_sliders=[], r_sliders=[])
    why = check_sent(el, handle, {"value": value})
    assert why is not None and why.startswith(f"{BY_NAME[name].label}: the value sent") and "\n" not in why
    assert check_sent(el, handle, {"value": 4 if name == "bits" else False}) is None
