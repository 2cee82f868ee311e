"""``python -m core.cli`` == ``clm``."""

import sys

from core.cli import main

sys.exit(main())
