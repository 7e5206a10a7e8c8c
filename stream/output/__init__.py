"""Files a command writes: output checks, atomic text files, strict JSON (``files``) and CSV numbers (``csv_text``)."""
