"""The live view in Rerun: ``logger.RerunLogger`` draws a session's frames, ``process.ViewProcess`` runs it in a
process of its own (what the view shows: ``logger``'s module docstring).

Importing this package imports nothing heavy (no rerun): import the module you need.
"""
