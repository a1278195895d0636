"""``python -m app.cli``: the same as ``qsid``."""

import sys

from app.cli import main

sys.exit(main())
