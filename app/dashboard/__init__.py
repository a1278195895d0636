"""qsid-dashboard: the live viser dashboard (``qsid-dashboard`` or ``python -m app.dashboard``).

The dashboard is viser wiring: what it shows is computed and arranged without any GUI in :mod:`app.frames`
(frames, summaries, figures, exports, the shared cache) from the values of :mod:`app.settings` (values, engine
configuration, settings files, view codes), with the lessons of :mod:`app.lessons`. Modules, in the order a
request flows through them:

- :mod:`~app.dashboard.server`: the viser server, shared cache and process pool, ``main``
  (:mod:`~app.dashboard.lifecycle`: its start-up, warm-up, memory and stop; :mod:`~app.dashboard.options`: its
  command line);
- :mod:`~app.dashboard.session`: one tab's worker and ALL of the dashboard's threading;
- :mod:`~app.dashboard.tabview`, :mod:`~app.dashboard.controls`, :mod:`~app.dashboard.viewpanel`,
  :mod:`~app.dashboard.share`, :mod:`~app.dashboard.scene`: the tab's panels and its 3-D nodes;
- :mod:`~app.dashboard.follow`: tabs that follow another tab live.
"""

import os
import signal
import sys
import threading

if "numpy" not in sys.modules:  # started as the program: many tiny matrices, BLAS threads only cost
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")
#: The first line on a terminal, before the imports.
LOADING = "qsid dashboard: loading its libraries …"
_program = sys.argv[:1] == ["-m"] or os.path.basename(sys.argv[0] if sys.argv else "") == "qsid-dashboard"
if _program and threading.current_thread() is threading.main_thread():
    # python -m app.dashboard / qsid-dashboard: a Ctrl-C while the imports below take their seconds ends the
    # program as the terminal expects, without a KeyboardInterrupt traceback; main() then takes the stop signals
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # (an ignored Ctrl-C stays ignored)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
    if sys.stdout.isatty() and not {"-h", "--help", "--version"} & set(sys.argv[1:]):
        # a terminal hears at once that the command started: the imports below take seconds (3 s on a quiet
        # machine, up to 21 s measured on a busy one); a pipe (a script, a service) gets only the lines below
        print(LOADING, flush=True)

from .server import DashboardApp, main  # noqa: E402
from .session import Session  # noqa: E402

__all__ = ["DashboardApp", "LOADING", "Session", "main"]
