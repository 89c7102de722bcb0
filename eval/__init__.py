"""Evaluation: reads run directories (``run.rrd``, ``frames.parquet``, ``metrics.json``), never calls the trackers."""
