"""``python -m switchest`` runs the command line.

A Ctrl-C while the command line is still importing (several seconds on a loaded
machine) exits with 130 like one inside :func:`switchest.cli.main`, without a
traceback.
"""

import sys

try:
    from .cli import main

    sys.exit(main())
except KeyboardInterrupt:
    print("interrupted", file=sys.stderr)
    sys.exit(130)
