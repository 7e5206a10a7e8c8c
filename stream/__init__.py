"""The live pipeline and its edges: acquisition thread, queue, tracker, recorder, viewer, CLI."""
