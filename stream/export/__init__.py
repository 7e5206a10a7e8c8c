"""What a recording becomes: CSV files (``export``: its columns in ``columns``, the recomputed strain in
``recomputed_strain``, the machine's force in ``force``, stopping in ``stop``, the reader's notes in ``notes``),
field maps, video and VTK (``field_export``), and the tensile report (``report``).
"""
