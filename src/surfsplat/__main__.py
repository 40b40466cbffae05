"""``python -m surfsplat ...``: the ``surfsplat`` command."""

import sys

from .cli import main

sys.exit(main())
