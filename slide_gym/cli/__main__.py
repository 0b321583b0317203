"""``python -m slide_gym.cli``: the same as the ``slide-gym`` command."""

import sys

from slide_gym.cli import main

sys.exit(main())
