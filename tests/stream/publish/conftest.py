"""Helpers shared by the strain-out tests."""

import socket


def assert_port_free(port):
    """No server listens on ``port`` any more: a new one can bind it (SO_REUSEADDR, as servers bind: a connection
    the closed server ended may sit in TIME_WAIT on it, which a plain bind refuses; seen once in CI)."""
    probe = socket.socket()
    try:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(("127.0.0.1", port))
        probe.listen(1)
    finally:
        probe.close()
