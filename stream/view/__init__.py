"""The live view in Rerun: what a session draws, how, and where it goes (docs/guide/live-view.md describes the view).

``logger.RerunLogger`` is the sink that draws (the only caller of rerun's logging); ``process.ViewProcess``
runs it in a process of its own. Its parts: ``entities`` (entity paths and styles), ``colour_scale`` and
``colour_bar``, ``xy_plot``, ``blueprint`` (the layout), ``viewer`` (the ``--viewer`` modes) and
``camera_image``. Importing this package imports nothing heavy (no rerun): import the module you need.
"""
