"""The ``flexmotion`` command line (offline planning, comparison, plots, design)."""
