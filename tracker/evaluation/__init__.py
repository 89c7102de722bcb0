"""How estimates are judged, per model: columns of a frame's row (truth, estimate, errors) and a run's figures.

An evaluation (registered with its model: ``MODELS.register(..., evaluation=...)``) has
``columns(model, truth, estimate)`` -> ``(per_part, per_frame)`` column dictionaries for one frame (``estimate``
None when nothing was estimated) and ``summarize(model, table)`` -> a run's accuracy figures from the frames
table (``table``: column name -> ``(rows,)`` array, one row per frame and part, frame-major); ``series`` names the
numeric columns worth a time series in the recording (per part where they are per part).
"""
