"""``python -m sweep``: the ``sweep`` command (:func:`sweep.cli.main`).

Floor 6 (with :mod:`sweep.cli`): imports the command line only.
"""
import sys

from sweep.cli import main

if __name__ == "__main__":
    sys.exit(main())
