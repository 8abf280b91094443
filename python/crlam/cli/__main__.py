"""``python -m crlam.cli``: the command line."""

import sys

from crlam.cli import main

sys.exit(main())
