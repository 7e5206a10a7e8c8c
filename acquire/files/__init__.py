"""Images from files: one image read and checked, and folders or globs of images as a frame source."""
