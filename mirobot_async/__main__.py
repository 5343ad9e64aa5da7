"""``python -m mirobot_async``: the ``mirobot`` command line (see :mod:`mirobot_async._cli`)."""

import sys

from mirobot_async._cli import main

if __name__ == "__main__":
    sys.exit(main())
