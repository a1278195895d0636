"""The dashboard's control panel for one browser tab (viser GUI handles).

:class:`Controls` builds every input in ``client.gui`` and reads them back as one
:class:`~app.dashboard_state.Values`. Every input's callback only calls
``on_change()`` (the session marks itself dirty); the session's worker thread
reads the values and recomputes.
"""

from __future__ import annotations

import threading
from typing import Callable

import numpy as np

from qsid_core.quantize import DITHERS, RANGE_MODES
from qsid_core.systems import LTISystem

from .dashboard_state import (
    IDENT_CHOICES, INTERACTIVE, LOG_MAX, LOG_MIN, PAPER_SCALE, SYSTEM_CHOICES, Values, axes_options,
    format_weights, log_from_weights, matrix_text, weights_from_log,
)

__all__ = ["Controls"]

MATRIX_HINT = "One row per line (or separate rows with ';'); numbers separated by spaces or commas."


class Controls:
    """All inputs of one tab, grouped in tabs: System, Quantizer, Data, Identify, MPC, Theory.

    Parameters
    ----------
    gui : viser.GuiApi
        ``client.gui`` of the tab.
    values : Values
        Initial values.
    system : LTISystem
        The initial system (its matrices fill the A and B boxes; its weights the Q/R sliders).
    on_change : callable()
        Called (from viser's callback threads) whenever an input changes.
    """

    def __init__(self, gui, values: Values, system: LTISystem, on_change: Callable[[], None]):
        self.gui = gui
        self._on_change = on_change
        self._muted_thread: int | None = None  # the thread whose value changes are not user changes
        self._inputs: list = []
        v = values

        self.title = gui.add_markdown("**qsid** · quantized data → identified model → MPC")
        self.bits = self._watch(gui.add_slider("word length b", 1, 16, 1, int(v.bits),
                                               hint="Bits per sample of the quantizer (1..16). "
                                                    "Curves show every b; the 3-D view shows this one."))
        self.progress = gui.add_progress_bar(0.0, animated=False)
        self.status = gui.add_markdown("starting …")
        self.error = gui.add_markdown("", visible=False)

        tabs = gui.add_tab_group()
        with tabs.add_tab("System"):
            self.system = self._watch(gui.add_dropdown("system", SYSTEM_CHOICES, initial_value=v.system,
                                                       hint="The true plant. 'custom': type A and B below."))
            self.a_text = self._watch(gui.add_text("A", v.a_text or matrix_text(system.A), multiline=True,
                                                   hint=MATRIX_HINT, disabled=v.system != "custom"))
            self.b_text = self._watch(gui.add_text("B", v.b_text or matrix_text(system.B), multiline=True,
                                                   hint=MATRIX_HINT, disabled=v.system != "custom"))
            self.system_note = gui.add_markdown(self._system_note(v.system))
            opts = axes_options(system.state_names)
            self.axes = self._watch(gui.add_dropdown("3-D axes", opts, initial_value=v.axes if v.axes in opts
                                                     else opts[0], visible=len(opts) > 1,
                                                     hint="Which three states the phase portrait draws."))
        with tabs.add_tab("Quantizer"):
            self.dither = self._watch(gui.add_dropdown("dither", DITHERS, initial_value=v.dither,
                                                       hint="subtractive: x~ = Q(x + w) - w, w ~ U[-ε/2, ε/2]"))
            self.range_mode = self._watch(gui.add_dropdown("range", RANGE_MODES, initial_value=v.range_mode,
                                                           hint="per-channel min/max, one shared range, "
                                                                "or a fixed range typed below"))
            self.fixed_range = self._watch(gui.add_text("fixed range", v.fixed_range,
                                                        visible=v.range_mode == "fixed",
                                                        hint="'lo, hi' for every channel, or one 'lo hi' "
                                                             "row per channel (states, then inputs)"))
            self.guard = self._watch(gui.add_checkbox("guard band", bool(v.guard),
                                                      hint="Widen the range by ε/2 each side: no overload"))
            with gui.add_folder("Dither realizations"):
                self.realizations = self._watch(gui.add_slider(
                    "realizations", 1, 100, 1, int(v.realizations),
                    hint=f"Independent dither draws per b (paper: {PAPER_SCALE['realizations']}, "
                         f"interactive default: {INTERACTIVE['realizations']})"))
                self.dither_seed = self._watch(gui.add_number("dither seed", int(v.dither_seed), min=0, step=1))
        with tabs.add_tab("Data"):
            self.trajectories = self._watch(gui.add_slider("trajectories", 1, 400, 1, int(v.trajectories),
                                                           hint="Training runs (paper: 200)"))
            self.steps = self._watch(gui.add_slider("steps", 10, 2000, 10, int(v.steps),
                                                    hint="Steps per training run (paper: 1000)"))
            self.data_seed = self._watch(gui.add_number("data seed", int(v.data_seed), min=0, step=1))
            self.paper_button = gui.add_button(
                "Paper scale (200 × 1000, 50 realizations)",
                hint="The letter's data size; the first full update takes a few seconds")
            self.interactive_button = gui.add_button(
                f"Interactive ({INTERACTIVE['trajectories']} × {INTERACTIVE['steps']}, "
                f"{INTERACTIVE['realizations']} realizations)")
            self.paper_button.on_click(lambda _: self.set_scale(PAPER_SCALE))
            self.interactive_button.on_click(lambda _: self.set_scale(INTERACTIVE))
        with tabs.add_tab("Identify"):
            self.identification = self._watch(gui.add_dropdown(
                "estimator", tuple(IDENT_CHOICES), initial_value=v.identification,
                hint="LS: least squares on quantized data. BCLS: bias-compensated LS "
                     "(subtracts the known dither noise T·diag(ε²/12))."))
            gui.add_markdown("LS is biased by the quantization noise (Theorem 1); BCLS removes that bias. "
                             "'LS + BCLS' draws both side by side (blue, red).")
        with tabs.add_tab("MPC"):
            self.horizon = self._watch(gui.add_slider("horizon", 1, 50, 1, int(v.horizon)))
            self.q_folder = gui.add_folder("Q diagonal (slider = log10 weight)")
            self.r_folder = gui.add_folder("R diagonal (slider = log10 weight)")
            self.weights_note = gui.add_markdown("")
            self.u_max = self._watch(gui.add_slider("input bound", 0.05, 10.0, 0.05, float(v.u_max),
                                                    hint="|u_i| <= this bound"))
            self.x0 = self._watch(gui.add_text("x0", v.x0 or ", ".join(f"{x:g}" for x in system.x0),
                                               hint="Initial state of the closed loop, one number per state"))
            self.mpc_steps = self._watch(gui.add_slider("closed-loop steps", 5, 300, 5, int(v.mpc_steps)))
        with tabs.add_tab("Theory"):
            self.theta = self._watch(gui.add_slider("θ", 0.05, 0.95, 0.05, float(v.theta),
                                                    hint="Share of the Lyapunov decrease used against the "
                                                         "model error (ultimate bound δ(ε))"))
            self.rho_auto = self._watch(gui.add_checkbox(
                "ρ auto", bool(v.rho_auto), hint="ρ = sqrt(λmax(P)/λmin(P))·‖x0‖ (engine default)"))
            self.rho = self._watch(gui.add_number("ρ", float(v.rho), min=1e-6, step=0.1, disabled=bool(v.rho_auto)))
        with gui.add_folder("Summary"):
            self.summary = gui.add_markdown("")
        self.q_sliders: list = []
        self.r_sliders: list = []
        self._sys_key = None
        self.set_system(system, v.log_q, v.log_r, reset=False)

    # ----- helpers --------------------------------------------------------------------------
    def _watch(self, handle):
        self._inputs.append(handle)
        handle.on_update(self._changed)
        return handle

    def _changed(self, _event) -> None:
        # only the worker's own adjustments (set_system) are muted; changes from any other thread count
        if self._muted_thread != threading.get_ident():
            self._on_change()

    @staticmethod
    def _system_note(name: str) -> str:
        if name == "custom":
            return "Type A (n × n) and B (n × m). " + MATRIX_HINT + " x0 = e1, Q = I, R = I by default."
        return f"Preset **{name}** (matrices shown read-only; pick 'custom' to edit a copy)."

    def set_scale(self, scale: dict) -> None:
        """The paper-scale / interactive buttons: set trajectories, steps and realizations."""
        self.trajectories.value = scale["trajectories"]
        self.steps.value = scale["steps"]
        self.realizations.value = scale["realizations"]

    def set_system(self, system: LTISystem, log_q=(), log_r=(), reset: bool = True) -> bool:
        """Adapt the inputs to ``system``: A/B boxes, Q/R sliders, x0, 3-D axes. True if anything changed."""
        key = (system.name, system.A.tobytes(), system.B.tobytes(), system.A.shape, system.B.shape)
        if key == self._sys_key:
            return False
        first = self._sys_key is None
        self._sys_key = key
        was = self._muted_thread
        self._muted_thread = threading.get_ident()
        try:
            custom = self.system.value == "custom"
            self.a_text.disabled = not custom
            self.b_text.disabled = not custom
            self.system_note.content = self._system_note(self.system.value)
            if not custom:
                self.a_text.value = matrix_text(system.A)
                self.b_text.value = matrix_text(system.B)
            q0 = log_from_weights(np.diag(system.Q))
            r0 = log_from_weights(np.diag(system.R))
            lq = tuple(log_q) if len(log_q) == system.n else q0
            lr = tuple(log_r) if len(log_r) == system.m else r0
            for h in self.q_sliders + self.r_sliders:
                h.remove()
            with self.q_folder:
                self.q_sliders = [self._watch(self.gui.add_slider(
                    f"Q {nm}", LOG_MIN, LOG_MAX, 0.1, float(x), hint=f"log10 of the weight of state {nm}"))
                    for nm, x in zip(system.state_names, lq)]
            with self.r_folder:
                self.r_sliders = [self._watch(self.gui.add_slider(
                    f"R {nm}", LOG_MIN, LOG_MAX, 0.1, float(x), hint=f"log10 of the weight of input {nm}"))
                    for nm, x in zip(system.input_names, lr)]
            if reset and not first:
                self.x0.value = ", ".join(f"{x:g}" for x in system.x0)
            opts = axes_options(system.state_names)
            self.axes.options = opts
            self.axes.visible = len(opts) > 1
            self.show_weights()
        finally:
            self._muted_thread = was
        return True

    def show_weights(self) -> None:
        q = weights_from_log([h.value for h in self.q_sliders])
        r = weights_from_log([h.value for h in self.r_sliders])
        self.weights_note.content = f"{format_weights('Q', q)}, {format_weights('R', r)}"

    def values(self) -> Values:
        """The current inputs as one immutable :class:`Values`."""
        self.fixed_range.visible = self.range_mode.value == "fixed"
        self.rho.disabled = bool(self.rho_auto.value)
        return Values(
            system=self.system.value, a_text=self.a_text.value, b_text=self.b_text.value,
            bits=int(self.bits.value), dither=self.dither.value, range_mode=self.range_mode.value,
            fixed_range=self.fixed_range.value, guard=bool(self.guard.value),
            realizations=int(self.realizations.value), dither_seed=int(self.dither_seed.value),
            trajectories=int(self.trajectories.value), steps=int(self.steps.value),
            data_seed=int(self.data_seed.value), identification=self.identification.value,
            horizon=int(self.horizon.value), log_q=tuple(float(h.value) for h in self.q_sliders),
            log_r=tuple(float(h.value) for h in self.r_sliders), u_max=float(self.u_max.value),
            x0=self.x0.value, mpc_steps=int(self.mpc_steps.value), theta=float(self.theta.value),
            rho_auto=bool(self.rho_auto.value), rho=float(self.rho.value), axes=self.axes.value,
        )
