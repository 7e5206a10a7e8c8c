"""Sub-pixel refinement methods, one module per method, and the kernels they share (hessian, linalg, keys_cubic)."""
