"""``python -m studio`` is ``clm-studio``."""

from __future__ import annotations

import sys

from studio.serve import main

sys.exit(main())
