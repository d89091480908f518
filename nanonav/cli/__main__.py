"""``python -m nanonav.cli``: the ``nanonav`` command."""

import sys

from nanonav.cli import main

sys.exit(main())
