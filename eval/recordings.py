"""Read images back out of a run's Rerun recording (``run.rrd``)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from rerun.chunk import RrdReader


def read_rgb_frames(rrd_path: str | Path, view: str) -> dict[int, np.ndarray]:
    """Frame -> ``(h, w, 3)`` uint8 RGB of ``world/cameras/<view>/image/rgb``, JPEG-encoded or raw."""
    entity = f"/world/cameras/{view}/image/rgb"
    images: dict[int, np.ndarray] = {}
    for chunk in RrdReader(rrd_path).stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        frames = batch.column("frame").to_pylist()
        names = batch.schema.names
        for row, frame in enumerate(frames):
            if "EncodedImage:blob" in names:
                blob = batch.column("EncodedImage:blob")[row].values[0].values.to_numpy(zero_copy_only=False)
                bgr = cv2.imdecode(blob, cv2.IMREAD_COLOR)
                images[frame] = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
            else:
                buffer = batch.column("Image:buffer")[row].values[0].values.to_numpy(zero_copy_only=False)
                image_format = batch.column("Image:format")[row].values[0].as_py()
                images[frame] = buffer.reshape(image_format["height"], image_format["width"], 3).copy()
    if not images:
        raise ValueError(f"{rrd_path} has no images at {entity}")
    return images
