"""The simulator: synthetic tensile and translation tests with exact truth (model, rendering, sources)."""
