"""The recording format (MCAP): schema and codecs, the container layer, the writer, the reader and recover."""
