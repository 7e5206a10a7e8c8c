"""The live pipeline: frame queue, acquisition thread, tracker loop, output thread and its sinks, progress bar."""
