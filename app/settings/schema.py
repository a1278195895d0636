"""Every setting of qsid declared once: :class:`Setting` and the table :data:`SETTINGS`.

A row says what the setting is (name, type, unit, allowed range or choices, default), how the panel
shows it (label, tab, folder, kind of input, hint), its ``qsid`` flag, where it goes in the engine's
configuration (``engine``: a dotted path into :class:`~qsid_core.SweepConfig`) and whether it changes
results or only the drawing. From the table come the ``qsid`` options (:mod:`app.settings.cli`), the
dashboard's panel (:mod:`app.dashboard.controls`) and its values (:class:`app.dashboard.settings.Values`),
the strict type check of a panel or file value (:func:`app.settings.check.check_setting`), the
``qsid sweep`` line (:mod:`app.settings.command`) and the stages a change invalidates
(:meth:`Setting.stages`, from the engine's own :mod:`qsid_core.studies.cache_keys`).

Defaults, choices and slider ends the engine owns are written as :class:`E` references (``E("sweep.theta")``)
and read from ``SweepConfig()``, ``MPCConfig()``, ``QuantizerSpec()`` on first use: importing this module
loads no numerics (``qsid --help`` stays fast).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

__all__ = [
    "E",
    "Setting",
    "SETTINGS",
    "BY_NAME",
    "engine",
    "resolve",
    "value_default",
    "cli_default",
    "hint_text",
    "DATA_GROUP",
    "WHATIF_GROUP",
    "MPC_GROUP",
    "LOOP_GROUP",
]


@dataclass(frozen=True)
class E:
    """A value the engine owns: a dotted path into :func:`engine`'s namespace (``"mpc.horizon"``)."""

    path: str


def engine() -> SimpleNamespace:
    """The engine's defaults and choices, imported on first use (``qsid --help`` never loads numpy).

    Returns a namespace with ``sweep`` (``SweepConfig(mpc=None)``), ``mpc`` (``MPCConfig()``), ``quant``
    (``QuantizerSpec()``), ``letter`` (``SweepConfig.letter()``), ``dithers``, ``range_modes``, ``estimators``,
    ``tracking``, ``u_max`` (the default bound of one input) and ``bits_lo`` / ``bits_hi`` (the default sweep's ends).
    """
    global _ENGINE
    if _ENGINE is None:
        from qsid_core import MPCConfig, QuantizerSpec, SweepConfig
        from qsid_core.control import TRACKING
        from qsid_core.identification import ESTIMATORS
        from qsid_core.quantization import DITHERS, RANGE_MODES

        sweep, mpc = SweepConfig(mpc=None), MPCConfig()
        _ENGINE = SimpleNamespace(
            sweep=sweep,
            mpc=mpc,
            quant=QuantizerSpec(),
            letter=SweepConfig.letter(mpc=None),
            dithers=DITHERS,
            range_modes=RANGE_MODES,
            estimators=ESTIMATORS,
            tracking=TRACKING,
            u_max=mpc.u_max[0] if isinstance(mpc.u_max, tuple) else mpc.u_max,
            bits_lo=sweep.bits[0],
            bits_hi=sweep.bits[-1],
        )
    return _ENGINE


_ENGINE: SimpleNamespace | None = None


def resolve(value: Any) -> Any:
    """``value`` with every :class:`E` reference (also inside a tuple) replaced by the engine's value."""
    if isinstance(value, E):
        obj: Any = engine()
        for part in value.path.split("."):
            obj = getattr(obj, part)
        return obj
    if isinstance(value, tuple):
        return tuple(resolve(v) for v in value)
    return value


@dataclass(frozen=True)
class Setting:
    """One setting, declared once.

    Parameters
    ----------
    name : str
        The dashboard's :class:`~app.dashboard.settings.Values` field and the settings file's key.
    type : type
        ``int``, ``float``, ``bool``, ``str`` or ``tuple`` (of floats): what the panel, the settings
        file and the CLI accept, checked before any conversion (an int is never a float, a bool never a number).
    default : value or E
        The default (the engine's where ``E``).
    label : str
        The panel's label (also names the setting in every message).
    control : {"slider", "number", "checkbox", "dropdown", "text"} or None
        The panel input; None: set elsewhere (the view panel, the weight sliders) or not in the panel.
    tab, folder : str
        Where in the panel ("" = above the tabs; folder: an optional folder inside the tab).
    slider : (lo, hi, step)
        A slider's range and step (values or E); a number box's step is ``step``.
    min, max : float
        Allowed range of the value everywhere (CLI, panel, file; the number box's ends).
    choices : tuple or E
        Allowed values of a dropdown or choice option (a dashboard-only list is added by the dashboard).
    unit : str
        The unit, said in help texts ("" = none).
    hint : str
        The panel's hint and, unless ``cli_help`` is given, the CLI's help; ``{engine}``, ``{panel}``,
        ``{lo}``, ``{hi}`` are filled in (:func:`hint_text`).
    flag : str or None
        The ``qsid`` flag generated from this row (None: none, or a hand-made one, ``cli_note``).
    cli_group : str
        The ``qsid`` option group of the flag.
    metavar, cli_help : str
        The flag's metavar and help text (the default is appended).
    cli_default : value
        The flag's default when it differs from ``default`` (e.g. None: "take it from --seed").
    engine : str or None
        Where the value goes in the engine: a dotted path into :class:`~qsid_core.SweepConfig`
        (``"data_seed"``, ``"quantizer.dither"``, ``"mpc.loop_seed"``); None for the front ends' own settings.
    display : bool
        True if the setting only changes what is drawn from results already computed.
    panel_default : value or None
        The panel's default where it differs (the interactive data size).
    values : bool
        False for a CLI-only setting (no :class:`~app.dashboard.settings.Values` field).
    cli_note : str
        How the CLI gives a setting whose flag is written by hand (its value is not the panel's).
    """

    name: str
    type: type
    default: Any
    label: str
    control: str | None = None
    tab: str = ""
    folder: str | None = None
    slider: tuple[Any, Any, Any] | None = None
    step: float | None = None
    min: float | None = None
    max: float | None = None
    choices: Any = ()
    unit: str = ""
    hint: str | None = None
    flag: str | None = None
    cli_group: str = ""
    metavar: str | None = None
    cli_help: str | None = None
    cli_default: Any = ...
    engine: str | None = None
    display: bool = False
    panel_default: Any = None
    values: bool = True
    cli_note: str = ""

    @property
    def dest(self) -> str:
        """The argparse destination of the flag (the setting's name)."""
        return self.name

    def stages(self) -> tuple[str, ...]:
        """The engine's cached stages a change of this setting invalidates (none if display-only or unkeyed).

        Read from :data:`qsid_core.studies.cache_keys.STAGE_GROUPS`: a stage is invalidated if one of its
        key groups holds ``engine`` (or a field containing it).
        """
        if self.display or self.engine is None:
            return ()
        from qsid_core.studies.cache_keys import KEY_PARTS, STAGE_GROUPS

        path = self.engine
        groups = {g for g, parts in KEY_PARTS.items() if any(path == p or path.startswith(p + ".") for p in parts)}
        return tuple(s for s, gs in STAGE_GROUPS.items() if groups & set(gs))


def hint_text(s: Setting, text: str | None = None) -> str | None:
    """The setting's hint (or ``text``) with ``{engine}`` (the engine's default), ``{panel}`` (the panel's) and
    ``{lo}``/``{hi}`` (a slider's ends) filled in."""
    text = s.hint if text is None else text
    if text is None:
        return None
    lo, hi, _ = resolve(s.slider) if s.slider is not None else (s.min, s.max, s.step)
    return text.format(engine=resolve(s.default), panel=value_default(s), lo=lo, hi=hi)


def value_default(s: Setting) -> Any:
    """The setting's default in the panel and the settings file."""
    return resolve(s.panel_default if s.panel_default is not None else s.default)


def cli_default(s: Setting, base: Any = None) -> Any:
    """The flag's default; ``base`` (a SweepConfig, e.g. the letter's, or a QuantizerSpec) replaces the engine's
    where it holds it."""
    if s.cli_default is not ...:
        return s.cli_default
    if base is not None and isinstance(s.default, E) and s.default.path.startswith(("sweep.", "quant.")):
        # base: a SweepConfig, or a QuantizerSpec for the quantizer's settings alone
        obj: Any = base if s.default.path.startswith("sweep.") else getattr(base, "quantizer", base)
        return getattr(obj, s.default.path.split(".", 1)[1])
    return resolve(s.default)


_R = "Dither realizations"
_V = "How many bits?"
_L = "Real loop"
#: The ``qsid`` option groups (``cli_group``) that hold settings of several kinds.
DATA_GROUP = "system and data"
WHATIF_GROUP = "what-ifs: word length per channel, sensor noise, a saved study"
MPC_GROUP = "MPC and ultimate bound"
LOOP_GROUP = "the real loop (disturbance and measurement)"
_DATA, _WHATIF, _MPC, _LOOP = DATA_GROUP, WHATIF_GROUP, MPC_GROUP, LOOP_GROUP
_MATRIX = "One row per line (or separate rows with ';'); numbers separated by spaces or commas."
_SEED_MAX = 2**32 - 1

#: Every setting, in the panel's display order (tabs appear in order of first use).
SETTINGS: tuple[Setting, ...] = (
    Setting(
        "lesson",
        str,
        "(none)",
        "lesson",
        "dropdown",
        hint="A lesson sets the controls and says what to look at (every claim is tested)",
    ),
    Setting(
        "bits",
        int,
        4,
        "word length b",
        "slider",
        slider=(E("bits_lo"), E("bits_hi"), 1),
        display=True,
        unit="bits",
        hint="Bits per sample of the quantizer ({lo}..{hi}). Curves show every b; the 3-D view shows this one.",
        cli_note="--bits SPEC: the word lengths swept (the panel draws all and shows this one in 3-D)",
    ),
    Setting(
        "presenter",
        bool,
        False,
        "presenter",
        "checkbox",
        display=True,
        hint="Lecture-hall layout: plot text 18 px, panel text 16 px, thick lines, a wide 3-D scene "
        "(both panels narrowed). Auto-play below steps b from 1 to 16.",
    ),
    Setting(
        "system",
        str,
        E("sweep.system"),
        "system",
        "dropdown",
        "System",
        hint="The true plant. 'custom': type A and B below.",
        cli_note="--system NAME|FILE",
    ),
    Setting("a_text", str, "", "A", "text", "System", hint=_MATRIX, cli_note="--A ROWS"),
    Setting("b_text", str, "", "B", "text", "System", hint=_MATRIX, cli_note="--B ROWS"),
    Setting(
        "axes",
        str,
        "",
        "3-D axes",
        "dropdown",
        "System",
        display=True,
        hint="Which three states the phase portrait draws.",
    ),
    Setting(
        "dither",
        str,
        E("quant.dither"),
        "dither",
        "dropdown",
        "Quantizer",
        choices=E("dithers"),
        engine="quantizer.dither",
        hint="subtractive: x~ = Q(x + w) - w, w ~ U[-ε/2, ε/2]. tpdf: Q(x + w), w triangular on [-ε, ε], "
        "not subtracted (error variance ε²/4, known). rpdf: Q(x + w), w uniform, not subtracted "
        "(variance depends on the signal: BCLS does not apply). none: Q(x)",
        flag="--dither",
        cli_group="quantizer",
        cli_help="subtractive uniform dither (the letter's), tpdf (non-subtractive triangular, width 2 eps: "
        "BCLS with D = eps^2/4), rpdf (non-subtractive uniform: BCLS not applicable) or none",
    ),
    Setting(
        "range_mode",
        str,
        E("quant.range_mode"),
        "range",
        "dropdown",
        "Quantizer",
        choices=E("range_modes"),
        engine="quantizer.range_mode",
        hint="per-channel min/max, one shared range, or a fixed range typed below",
        flag="--range",
        cli_group="quantizer",
        cli_help="quantizer range: min/max per channel, one range for all, or fixed (--limits)",
    ),
    Setting(
        "fixed_range",
        str,
        "-1, 1",
        "fixed range",
        "text",
        "Quantizer",
        engine="quantizer.fixed_range",
        hint="'lo, hi' for every channel, or one 'lo hi' row per channel (states, then inputs)",
        cli_note="--limits LO,HI[;LO,HI...]",
    ),
    Setting(
        "guard",
        bool,
        E("quant.guard"),
        "guard band",
        "checkbox",
        "Quantizer",
        engine="quantizer.guard",
        hint="Widen the range by the dither's amplitude each side (ε/2; ε for tpdf): no overload",
        flag="--guard",
        cli_group="quantizer",
        cli_help="widen the range by the dither's amplitude on each side (half a cell; a cell for tpdf), "
        "so x + w never overloads",
    ),
    Setting(
        "state_bits",
        str,
        "b",
        "state bits",
        "text",
        "Quantizer",
        engine="state_bits",
        hint="Word length of the states: 'b' (the slider's b, as the letter), or one entry for all or one "
        "per state, each 'b', a number or 'exact', like 'b, b, 12, exact'",
        flag="--state-bits",
        cli_group=_WHATIF,
        metavar="E|E1,E2,..",
        cli_default=None,
        cli_help="word length of the states, one entry for all or one per state: 'b' (the swept --bits), "
        "a fixed word length, or 'exact' (not quantized), e.g. 'b,b,12,exact' (default: all b)",
    ),
    Setting(
        "input_bits",
        str,
        "same",
        "input bits",
        "text",
        "Quantizer",
        engine="input_bits",
        hint="Word length of the inputs: 'same' (= b, as the letter), 'exact' (inputs not quantized), "
        "one number for all inputs, or one per input like '8, exact'; b then sweeps the states",
        flag="--input-bits",
        cli_group=_WHATIF,
        metavar="B|exact|B1,B2,..",
        cli_default=None,
        cli_help="word length of the inputs: one for all, one per input ('8,exact'), or 'exact' (inputs "
        "recorded without quantization); --bits then sweeps the states (default: same as --bits)",
    ),
    Setting(
        "realizations",
        int,
        E("sweep.realizations"),
        "realizations",
        "slider",
        "Quantizer",
        _R,
        slider=(1, 100, 1),
        min=1,
        panel_default=20,
        engine="realizations",
        hint="Independent dither draws per b (paper: {engine}, interactive default: {panel})",
        flag="--realizations",
        cli_group=_DATA,
        metavar="N",
        cli_help="dither realizations per word length",
    ),
    Setting(
        "dither_seed",
        int,
        E("sweep.dither_seed"),
        "dither seed",
        "number",
        "Quantizer",
        _R,
        step=1,
        min=0,
        max=_SEED_MAX,
        engine="dither_seed",
        flag="--dither-seed",
        cli_group=_DATA,
        metavar="N",
        cli_default=None,
        cli_help="seed of the dither streams",
    ),
    Setting(
        "trajectories",
        int,
        E("sweep.trajectories"),
        "trajectories",
        "slider",
        "Data",
        slider=(1, 400, 1),
        min=1,
        panel_default=50,
        engine="trajectories",
        hint="Training runs (paper: {engine})",
        flag="--trajectories",
        cli_group=_DATA,
        metavar="N",
        cli_help="simulated trajectories",
    ),
    Setting(
        "steps",
        int,
        E("sweep.steps"),
        "steps",
        "slider",
        "Data",
        slider=(10, 2000, 10),
        min=1,
        panel_default=200,
        engine="steps",
        hint="Steps per training run (paper: {engine})",
        flag="--steps",
        cli_group=_DATA,
        metavar="N",
        cli_help="samples per trajectory",
    ),
    Setting(
        "data_seed",
        int,
        E("sweep.data_seed"),
        "data seed",
        "number",
        "Data",
        step=1,
        min=0,
        max=_SEED_MAX,
        engine="data_seed",
        flag="--data-seed",
        cli_group=_DATA,
        metavar="N",
        cli_default=None,
        cli_help="seed of the simulated data",
    ),
    Setting(
        "input_amplitude",
        float,
        E("sweep.input_amplitude"),
        "input amplitude",
        "number",
        "Data",
        step=0.1,
        min=1e-6,
        max=1e12,
        unit="input units",
        engine="input_amplitude",
        hint="Training inputs u ~ U[-A, A] (the letter: A = 1). Small A: a small signal against the quantizer range",
        flag="--input-amplitude",
        cli_group=_DATA,
        metavar="A",
        cli_help="training inputs u ~ U[-A, A], in input units (the letter's: 1)",
    ),
    Setting(
        "noise",
        str,
        "",
        "sensor noise σ",
        "text",
        "Data",
        engine="noise",
        hint="Gaussian noise added to the recorded states before quantization: one σ for every state or "
        "one per state (empty = none; seeded by the data seed)",
        flag="--noise",
        cli_group=_WHATIF,
        metavar="SIGMA|S1,S2,..",
        cli_default=None,
        cli_help="standard deviation of Gaussian sensor noise added to the recorded states before "
        "quantization, one for all or one per state (seeded by the data seed; default: 0)",
    ),
    Setting(
        "identification",
        str,
        "LS + BCLS",
        "estimator",
        "dropdown",
        "Identify",
        hint="LS: least squares on quantized data. BCLS: bias-compensated LS "
        "(subtracts the known noise T·diag(D): ε²/12 subtractive, ε²/4 tpdf dither).",
        cli_note="--estimator ls|bcls (one per line of 'As a command')",
    ),
    Setting(
        "estimator",
        str,
        E("sweep.estimator"),
        "estimator",
        choices=E("estimators"),
        engine="estimator",
        values=False,
        flag="--estimator",
        cli_group="identification",
        cli_help="least squares or bias-compensated LS",
    ),
    Setting(
        "noise_known",
        bool,
        E("sweep.noise_known"),
        "sensor noise known to BCLS",
        "checkbox",
        "Identify",
        engine="noise_known",
        hint="BCLS adds σ² to D; unticked, BCLS corrects only the quantization noise it knows of",
        flag="--noise-known",
        cli_group=_WHATIF,
        cli_help="BCLS adds the noise variance sigma^2 to D (without it BCLS corrects only the "
        "quantization noise it knows of)",
    ),
    Setting(
        "horizon",
        int,
        E("mpc.horizon"),
        "horizon",
        "slider",
        "MPC",
        slider=(1, 50, 1),
        min=1,
        unit="steps",
        engine="mpc.horizon",
        flag="--horizon",
        cli_group=_MPC,
        metavar="N",
        cli_help="MPC horizon",
    ),
    Setting(
        "u_max",
        float,
        E("u_max"),
        "input bound",
        "slider",
        "MPC",
        slider=(0.05, 10.0, 0.05),
        engine="mpc.u_max",
        hint="|u_i| <= this bound",
        cli_note="--u-max X[,X2,..] (one value or one per input)",
    ),
    Setting(
        "x0",
        str,
        "",
        "x0",
        "text",
        "MPC",
        engine="mpc.x0",
        hint="Initial state of the closed loop, one number per state",
        cli_note="--x0 X1,X2,..",
    ),
    Setting(
        "mpc_steps",
        int,
        E("mpc.steps"),
        "closed-loop steps",
        "slider",
        "MPC",
        slider=(5, 300, 5),
        min=1,
        engine="mpc.steps",
        flag="--mpc-steps",
        cli_group=_MPC,
        metavar="N",
        cli_help="closed-loop steps on the true system",
    ),
    Setting(
        "x_ref",
        str,
        "",
        "reference x_ref",
        "text",
        "MPC",
        engine="mpc.x_ref",
        hint="Constant reference, one number per state (empty = regulate to 0). δ(ε) assumes x_ref = 0.",
        cli_note="--x-ref R1,R2,..",
    ),
    Setting(
        "reference",
        str,
        "",
        "reference r(t)",
        "text",
        "MPC",
        engine="mpc.reference",
        hint="Time-varying reference with preview: step:STATE:AMP:TIME, sine:STATE:AMP:PERIOD or "
        "square:STATE:AMP:PERIOD (STATE a name or 1-based, times in samples); empty = constant x_ref",
        flag="--reference",
        cli_group=_MPC,
        metavar="SPEC|FILE.csv",
        cli_default=None,
        cli_help="time-varying reference the MPC tracks with preview: step:STATE:AMPLITUDE:TIME, "
        "sine:STATE:AMPLITUDE:PERIOD, square:STATE:AMPLITUDE:PERIOD (STATE a name or 1-based "
        "index, times in samples) or a CSV file with one row per step and one column per state; "
        "excludes --x-ref",
    ),
    Setting(
        "tracking",
        str,
        E("mpc.tracking"),
        "tracking form",
        "dropdown",
        "MPC",
        choices=E("tracking"),
        engine="mpc.tracking",
        hint="letter: cost u'Ru (a reference that is no equilibrium leaves an offset); offset-free: "
        "(u - u_ref)'R(u - u_ref) with u_ref = B^+(I - A^) r, the input that holds the model at r",
        flag="--tracking",
        cli_group=_MPC,
        cli_help="the cost's input term: the letter's u'Ru, or offset-free (u - u_ref)'R(u - u_ref) with "
        "u_ref = B^+ (I - A^) r, the input that holds the model at the reference",
    ),
    Setting(
        "x_max",
        str,
        "",
        "state box x_max",
        "text",
        "MPC",
        engine="mpc.x_max",
        hint="|x_i| <= x_max_i over the horizon: one number for every state or one per state (empty = none)",
        cli_note="--x-max X",
    ),
    Setting(
        "qf",
        str,
        "dare",
        "terminal weight Qf",
        "text",
        "MPC",
        engine="mpc.Qf",
        hint="'dare' (each model's stabilizing DARE solution, default), 'Q' (the stage weight) or a "
        "diagonal: one number for every state or one per state",
        cli_note="--Qf dare|Q|F1,F2,..",
    ),
    Setting(
        "terminal_box",
        str,
        "",
        "terminal box",
        "text",
        "MPC",
        engine="mpc.xf_max",
        hint="|x_N,i| <= X_i on the last predicted state: one number for every state or one per state (empty = none)",
        cli_note="--terminal-box X",
    ),
    Setting(
        "disturbance",
        float,
        E("mpc.disturbance"),
        "disturbance σ",
        "number",
        "MPC",
        _L,
        step=0.005,
        min=0.0,
        max=1e9,
        engine="mpc.disturbance",
        hint="Process noise added to the true plant in the closed loop (standard deviation; the same draws "
        "for every b, estimator and the true-model loop)",
        cli_note="--disturbance SIGMA[:gaussian|uniform] (with the kind)",
    ),
    Setting(
        "disturbance_kind",
        str,
        E("mpc.disturbance_kind"),
        "disturbance kind",
        "dropdown",
        "MPC",
        _L,
        choices=("gaussian", "uniform"),
        engine="mpc.disturbance_kind",
        cli_note="--disturbance SIGMA:KIND",
    ),
    Setting(
        "feedback_bits",
        int,
        0,
        "feedback bits",
        "slider",
        "MPC",
        _L,
        slider=(0, 16, 1),
        min=0,
        engine="mpc.feedback_bits",
        hint="The MPC measures the state through this many bits per state (subtractive dither, the training "
        "data's range); 0 = exact state",
        cli_note="--feedback-bits B|none (none = the panel's 0)",
    ),
    Setting(
        "feedback_noise",
        float,
        E("mpc.feedback_noise"),
        "sensor noise σ",
        "number",
        "MPC",
        _L,
        step=0.005,
        min=0.0,
        max=1e9,
        engine="mpc.feedback_noise",
        hint="Noise on the state the MPC measures (standard deviation)",
        flag="--feedback-noise",
        cli_group=_LOOP,
        metavar="SIGMA",
        cli_help="sensor noise (standard deviation) on that measurement",
    ),
    Setting(
        "loop_seed",
        int,
        E("mpc.loop_seed"),
        "loop seed",
        "number",
        "MPC",
        _L,
        step=1,
        min=0,
        max=1e9,
        engine="mpc.loop_seed",
        flag="--loop-seed",
        cli_group=_LOOP,
        metavar="N",
        cli_help="seed of the disturbance, feedback dither and sensor noise",
    ),
    Setting(
        "verify_steps",
        int,
        E("mpc.verify_steps"),
        "verdict steps",
        "number",
        "MPC",
        _V,
        step=500,
        min=0,
        max=1e9,
        engine="mpc.verify_steps",
        hint="At most this many extra closed-loop steps to decide whether a loop converges, stays bounded "
        "or diverges on the true plant (where the spectral radius alone does not decide)",
        flag="--verify-steps",
        cli_group=_MPC,
        metavar="N",
        cli_help="at most N closed-loop steps beyond --mpc-steps to decide whether a loop converges, stays "
        "bounded or diverges on the true plant (0: judge from the run alone where the spectral radius "
        "and the certificate decide, else call it bounded)",
    ),
    Setting(
        "target",
        float,
        0.95,
        "target stabilized",
        "slider",
        "MPC",
        _V,
        slider=(0.5, 1.0, 0.01),
        hint="b_observed: the smallest b from which on at least this share of the loops converge …",
        cli_note="qsid bits --target X",
    ),
    Setting(
        "cost_gap",
        float,
        0.01,
        "cost gap",
        "number",
        "MPC",
        _V,
        step=0.005,
        min=0.0,
        max=1e9,
        hint="… and the mean closed-loop cost is within this relative gap of the true model's (0.01 = 1 %)",
        cli_note="qsid bits --cost-gap X",
    ),
    Setting(
        "theta",
        float,
        E("sweep.theta"),
        "θ",
        "slider",
        "Theory",
        slider=(0.05, 0.95, 0.05),
        engine="theta",
        hint="Share of the Lyapunov decrease used against the model error (ultimate bound δ(ε))",
        flag="--theta",
        cli_group=_MPC,
        metavar="X",
        cli_help="theta of the ultimate bound, in (0, 1)",
    ),
    Setting(
        "rho_auto",
        bool,
        True,
        "ρ auto",
        "checkbox",
        "Theory",
        engine="rho",
        hint="ρ = sqrt(x0ᵀP x0 / λmin(P)), the smallest ball holding {{V ≤ V(x0)}} (engine default)",
        cli_note="no --rho",
    ),
    Setting(
        "rho",
        float,
        1.0,
        "ρ",
        "number",
        "Theory",
        step=0.1,
        min=1e-6,
        max=1e6,
        engine="rho",
        cli_note="--rho X",
    ),
    Setting(
        "show_bound",
        bool,
        True,
        "bound in 3-D",
        "checkbox",
        "Theory",
        display=True,
        hint="Draw the ultimate bounds as circles in the 3-D view (hide them to see the loops alone)",
    ),
    # set by the weight sliders (one per state / input, built per system) and by the view panel
    Setting("log_q", tuple, (), "Q weights (log10)", engine="mpc.Q", cli_note="--Q Q1,Q2,.."),
    Setting("log_r", tuple, (), "R weights (log10)", engine="mpc.R", cli_note="--R R1,R2,.."),
    Setting("view_channel", int, 0, "quantizer view channel", min=0, max=1e9, display=True),
    Setting("compare_bits", str, "2, 4, 6", "compared word lengths", display=True),
)

#: The settings by name.
BY_NAME: dict[str, Setting] = {s.name: s for s in SETTINGS}
