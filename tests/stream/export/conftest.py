"""Helpers shared by the export tests."""

import os


def partial_files(folder):
    """The temporary files (``.livedic-*``) an unfinished write would leave anywhere under ``folder``."""
    return [os.path.join(top, name) for top, _, names in os.walk(folder) for name in names
            if name.startswith(".livedic-")]
