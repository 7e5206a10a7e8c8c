"""Frame sources: cameras (Aravis, V4L2), files, recordings and the simulator."""
