"""``python -m livedic.stream.cli``: the ``livedic`` command line without the layers above it (no ``livedic bench``)."""

import sys

from livedic.stream.cli.main import entry_point

if __name__ == "__main__":
    sys.exit(entry_point())
