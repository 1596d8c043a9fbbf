"""``python -m vpforms.cli``."""

import sys

from . import main

sys.exit(main())
