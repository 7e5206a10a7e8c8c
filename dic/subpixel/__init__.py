"""Sub-pixel refinement methods, one module per method."""
