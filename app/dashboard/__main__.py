"""``python -m app.dashboard``: the same as ``qsid-dashboard``."""

import sys

from app.dashboard import main

sys.exit(main())
