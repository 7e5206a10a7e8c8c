"""Helpers of the force tests: a load opened for a block, force CSVs, a free port (helpers, not tests)."""

import contextlib
import socket

from livedic.acquire.force import open_load


@contextlib.contextmanager
def loading(uri, **options):
    """``open_load(uri, **options)``, closed at the end of the block."""
    source = open_load(uri, **options)
    try:
        yield source
    finally:
        source.close()


def free_port():
    """A local TCP port that nothing listens on (bound, then released)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def write_csv(path, rows, header="time_s,force_N"):
    """A force CSV at ``path``: ``header``, then one line per row; returns ``path``."""
    path.write_text(header + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows))
    return path
