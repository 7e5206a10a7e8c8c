"""What a recording becomes: CSV files (``export``), field maps, video and VTK (``field_export``), and the
tensile report (``report``).
"""
