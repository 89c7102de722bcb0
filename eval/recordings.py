"""Read images back out of a run's Rerun recording (``run.rrd``)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from rerun.chunk import RrdReader

from eval.video import decode


def read_rgb_frames(rrd_path: str | Path, view: str) -> dict[int, np.ndarray]:
    """Frame -> ``(h, w, 3)`` uint8 RGB of ``world/cameras/<view>/image/rgb``: the view's video decoded, each
    frame the one its frame reference names (or, in recordings of images, the image itself)."""
    entity = f"/world/cameras/{view}/image/rgb"
    video, references = None, {}
    for chunk in RrdReader(rrd_path).stream().to_chunks():
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        if "AssetVideo:blob" in batch.schema.names:
            video = batch.column("AssetVideo:blob")[0].values[0].values.to_numpy(zero_copy_only=False).tobytes()
        elif "VideoFrameReference:timestamp" in batch.schema.names:
            stamps = [value[0] for value in batch.column("VideoFrameReference:timestamp").to_pylist()]
            references.update(zip(batch.column("frame").to_pylist(), stamps, strict=True))
    if video is None:
        return read_images(rrd_path, entity)
    frames = decode(video)
    order = {stamp: k for k, stamp in enumerate(sorted(set(references.values())))}
    return {frame: frames[order[stamp]] for frame, stamp in references.items()}


# Rerun's channel datatypes (rerun.datatypes.ChannelDatatype) and colour models (rerun.datatypes.ColorModel).
_DTYPES = {6: np.uint8, 7: np.int8, 8: np.uint16, 9: np.int16, 10: np.uint32, 11: np.int32, 12: np.uint64,
           13: np.int64, 33: np.float16, 34: np.float32, 35: np.float64}  # fmt: skip
_CHANNELS = {1: 1, 2: 3, 3: 4, 4: 3, 5: 4}  # L, RGB, RGBA, BGR, BGRA
_RAW = ("Image", "SegmentationImage", "DepthImage")


def read_images(rrd_path: str | Path, entity: str) -> dict[int, np.ndarray]:
    """Frame -> image logged at ``entity`` (an ``/``-rooted entity path): encoded ones (JPEG, PNG) decoded
    (colour to RGB), raw ones (images, segmentation and depth images) in their own type; ``(h, w)`` for one
    channel."""
    images: dict[int, np.ndarray] = {}
    for chunk in RrdReader(rrd_path).stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        kind = next((kind for kind in _RAW if f"{kind}:buffer" in names), None)
        for row, frame in enumerate(batch.column("frame").to_pylist()):
            if "EncodedImage:blob" in names:
                blob = batch.column("EncodedImage:blob")[row].values[0].values.to_numpy(zero_copy_only=False)
                decoded = cv2.imdecode(blob, cv2.IMREAD_UNCHANGED)
                images[frame] = cv2.cvtColor(decoded, cv2.COLOR_BGR2RGB) if decoded.ndim == 3 else decoded
            elif kind is not None:
                raw = batch.column(f"{kind}:buffer")[row].values[0].values.to_numpy(zero_copy_only=False)
                image_format = batch.column(f"{kind}:format")[row].values[0].as_py()
                channels = _CHANNELS.get(image_format.get("color_model") or 1, 1)
                pixels = np.frombuffer(raw.tobytes(), dtype=_DTYPES[image_format["channel_datatype"]])
                shape = (image_format["height"], image_format["width"]) + ((channels,) if channels > 1 else ())
                images[frame] = pixels.reshape(shape).copy()
    if not images:
        raise ValueError(f"{rrd_path} has no images at {entity}")
    return images


def read_mesh_vertices(rrd_path: str | Path, entity: str) -> dict[int, np.ndarray]:
    """Frame -> ``(n, 3)`` world vertices of the Mesh3D at ``entity`` as the viewer shows them at that frame: its
    latest vertex positions moved by its latest Transform3D (identity before one is logged), for every frame at
    which either was logged."""
    logged: dict[int, dict[str, np.ndarray]] = {}
    for chunk in RrdReader(rrd_path).stream().to_chunks():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        names = batch.schema.names
        for row, frame in enumerate(batch.column("frame").to_pylist()):
            for component in ("Mesh3D:vertex_positions", "Transform3D:translation", "Transform3D:mat3x3"):
                value = batch.column(component)[row].as_py() if component in names else None
                if value:  # a list of one or more instances
                    logged.setdefault(frame, {})[component] = np.asarray(value, dtype=np.float64)
    meshes, vertices, transform = {}, None, np.eye(4)
    for frame in sorted(logged):
        values = logged[frame]
        vertices = values.get("Mesh3D:vertex_positions", vertices)
        if "Transform3D:translation" in values:
            transform = np.eye(4)
            transform[:3, 3] = values["Transform3D:translation"][0]
            transform[:3, :3] = values["Transform3D:mat3x3"][0].reshape(3, 3).T  # Rerun stores it column-major
        if vertices is None:
            raise ValueError(f"{rrd_path}: {entity} moves at frame {frame} before it has vertices")
        meshes[frame] = vertices @ transform[:3, :3].T + transform[:3, 3]
    return meshes
