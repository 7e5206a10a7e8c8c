"""Cameras: GenICam cameras through Aravis (features, pixel formats, fake cameras for tests), V4L2 and video files."""
