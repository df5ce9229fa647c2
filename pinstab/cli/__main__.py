"""``python -m pinstab.cli``."""

import sys

from .dispatch import main

sys.exit(main())
