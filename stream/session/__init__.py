"""A live session: its configuration, the points it tracks (P0 included), the set-up preview, and ``Session`` itself."""
