"""The one module that writes Rerun recordings: a run's frames, captures and tracker results -> ``run.rrd``.

Entity paths (timeline ``frame``): ``world/cameras/<view>`` (Transform3D + Pinhole, static) with
``.../image/rgb`` (the view's frames as one AV1 video, `eval.video`, and a frame reference per frame),
``.../image/labels`` (the render's part labels), ``.../image/silhouette`` (the extracted silhouette, runs that
capture silhouettes) and the tracker's overlays ``.../image/<name>`` (its `StepResult.points`);
``world/truth/<part>`` and ``world/estimate/<part>`` (Mesh3D, and Transform3D, when they change); series
``metrics/params/<name>/{truth,estimate}`` (the model's `parameter_series`), ``metrics/error/...`` (the columns
the model's evaluation names), ``metrics/visible_px/<view>/<part>``, ``metrics/timing/<stage>_ms`` (the tracker's own
stages ``metrics/timing/estimate/<stage>_ms``) and the tracker's own ``metrics/<name>`` (`StepResult.series`), each
with its colour (static ``SeriesLines``); ``capture/<view>/weights/<cost>`` (each registered cost's
weight map d_P, float images, when asked for), ``metrics/silhouette_iou/<view>``; ``log`` (failed frames).

Sized for keeping: rows are batched into large chunks (a few hundred per run instead of one per entity and frame,
so the file compresses across frames and the viewer loads it whole), images go as video, and a mesh's vertices are
written again only when its shape changed (a part that moved rigidly gets a Transform3D of its last vertices).
Nothing here knows a tracker: colours and panels come from the components' registrations (`tracker.presentation`,
laid out by `experiments.presentation`). Each recording has its own ``recording_id`` and a default blueprint; its
file is `experiments.recording_file`'s (no partial file is ever left).
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import rerun as rr

from eval.video import VideoEncoder
from experiments.components import Components
from experiments.presentation import (
    PALETTE,
    POINTS,
    SERIES_WIDTH_PX,
    run_blueprint,
    series_colors,
    shown_looks,
    weight_map_costs,
)
from experiments.recorded_meshes import MeshLog
from experiments.recording_file import RecordingFile
from experiments.schemas import RecordSettings
from tracker.geometry.cameras import Camera
from tracker.observe.silhouettes import CapturedFrame
from tracker.protocol import Points, RenderedFrame, StepResult
from tracker.tbf.costs import weight_map

TIMELINE = "frame"
SILHOUETTE = [
    rr.AnnotationInfo(id=0, label="outside", color=(0, 0, 0, 0)),
    rr.AnnotationInfo(id=1, label="silhouette", color=(255, 230, 0, 255)),
]


class RunRecording:
    """A run's Rerun recording written to ``path``. Use as a context manager, or call `close`."""

    def __init__(self, path: str | Path, components: Components, record: RecordSettings) -> None:
        self.path = Path(path)
        self.recording_id = str(uuid.uuid4())
        self.model, self.record, self.evaluation = components.model, record, components.evaluation
        self.weight_maps = weight_map_costs(components, record)
        looks = shown_looks(components)[::-1]  # the tracker's colours over the model's
        self._state_colors = {state: colour for look in looks for state, colour in look.state_colors.items()}
        self._point_colors = {name: colour for look in looks for name, colour in look.point_colors.items()}
        # Series named after a part or a point state take its colour in their plots (`series_colors`).
        parts = zip(self.model.part_names, self.model.part_colors, strict=True)
        self._series_names = {name: tuple(int(c) for c in colour) for name, colour in parts} | self._state_colors
        self._videos = (
            {
                camera.name: VideoEncoder(camera.width, camera.height, record.video_quality)
                for camera in components.cameras
            }
            if record.images
            else {}
        )
        self._blueprint = run_blueprint(components, record)
        self._file = RecordingFile(self.path, self.recording_id, self._blueprint)
        self.stream = self._file.stream
        self._log_static(components.cameras)
        self._static: set[str] = set()  # entities whose point states (classes, colours) are logged
        self._meshes = MeshLog(self.stream)  # meshes written again only when they change shape
        self._frames: list[int] = []  # the run's frames, as logged
        self._series: dict[str, tuple[list[int], list[float]]] = {}  # entity -> its frames and values, sent on close

    def __enter__(self) -> RunRecording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _log_static(self, cameras: Sequence[Camera]) -> None:
        log = self.stream.log
        log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        classes = [rr.AnnotationInfo(id=0, label="background", color=(0, 0, 0))]
        classes += [
            rr.AnnotationInfo(id=k + 1, label=name, color=tuple(color))
            for k, (name, color) in enumerate(zip(self.model.part_names, self.model.part_colors, strict=True))
        ]
        log("world", rr.AnnotationContext(classes), static=True)
        for camera in cameras:
            log(
                f"world/cameras/{camera.name}",
                rr.Transform3D(translation=camera.position, mat3x3=camera.rotation),
                static=True,
            )
            log(
                f"world/cameras/{camera.name}/image",
                rr.Pinhole(
                    image_from_camera=camera.intrinsic_matrix,
                    resolution=[camera.width, camera.height],
                    camera_xyz=rr.ViewCoordinates.RDF,
                ),
                static=True,
            )
            log(f"world/cameras/{camera.name}/image/silhouette", rr.AnnotationContext(SILHOUETTE), static=True)

    def log_frame(self, frame: RenderedFrame) -> None:
        """Images, truth meshes, truth parameters and label areas of one frame (timings: `log_timings`)."""
        self.stream.set_time(TIMELINE, sequence=frame.frame)
        self._frames.append(frame.frame)
        log = self.stream.log
        for view, rendered in frame.views.items():
            if self.record.images:
                self._videos[view].add(rendered.rgb)
                log(f"world/cameras/{view}/image/labels", rr.SegmentationImage(rendered.labels, opacity=0.35))
            for part, pixels in zip(self.model.part_names, frame.visible_px[view], strict=True):
                self._scalar(f"metrics/visible_px/{view}/{part}", pixels)
        if self._meshes_due(frame.frame):
            self._meshes.log("truth", frame.meshes)
        self._log_params("truth", frame.truth)

    def log_capture(self, captured: CapturedFrame) -> None:
        """Each view's extracted silhouette (over its image), the costs' weight maps of it, its IoU."""
        log = self.stream.log
        for view, silhouette in captured.silhouettes.items():
            if self.record.images:
                log(
                    f"world/cameras/{view}/image/silhouette",
                    rr.SegmentationImage(silhouette.astype(np.uint8), opacity=0.4),
                )
            if silhouette.any():
                for cost in self.weight_maps:
                    log(f"capture/{view}/weights/{cost}", rr.Image(weight_map(cost, silhouette).astype(np.float32)))
            if view in captured.iou:
                self._scalar(f"metrics/silhouette_iou/{view}", captured.iou[view])

    def log_result(self, result: StepResult, evaluated: tuple[dict, dict] = ({}, {})) -> None:
        """A tracker's result for the frame (call after `log_frame`): the estimate (its meshes when they moved, its
        parameters), the tracker's series, points and images, the evaluation's error series (``evaluated``: its
        per-part and per-frame columns), and why the frame failed if it did."""
        log = self.stream.log
        if result.estimate is not None:
            if self._meshes_due(result.frame):
                self._meshes.log("estimate", self.model.surface_meshes(result.estimate), rgba=(255, 255, 0, 120))
            self._log_params("estimate", result.estimate)
        series = dict(result.series)
        for column in getattr(self.evaluation, "series", ()):
            if column in evaluated[0]:
                series.update(
                    {
                        f"error/{part}/{column}": value
                        for part, value in zip(self.model.part_names, evaluated[0][column], strict=True)
                    }
                )
            elif column in evaluated[1]:
                series[f"error/{column}"] = evaluated[1][column]
        for name, value in series.items():
            self._scalar(f"metrics/{name}", value)
        for view, overlays in result.points.items() if self.record.images else ():  # drawn on the images
            for name, points in overlays.items():
                self._log_points(f"world/cameras/{view}/image/{name}", name, points)
        for view, images in result.images.items() if self.record.images else ():
            for name, image in images.items():
                log(f"world/cameras/{view}/image/{name}", rr.Image(np.asarray(image)))
        if result.failure:
            log("log", rr.TextLog(f"frame {result.frame} failed: {result.failure}", level=rr.TextLogLevel.WARN))

    def _log_points(self, path: str, name: str, points: Points) -> None:
        if not points.states:
            self.stream.log(path, rr.Points2D(points.uv, colors=[self._point_colors.get(name, POINTS)], radii=0.6))
            return
        if path not in self._static:  # the states' names and colours, once per entity
            colours = [self._state_colors.get(s, PALETTE[k % len(PALETTE)]) for k, s in enumerate(points.states)]
            classes = [
                rr.AnnotationInfo(id=k, label=state, color=colour)
                for k, (state, colour) in enumerate(zip(points.states, colours, strict=True))
            ]
            self.stream.log(path, rr.AnnotationContext(classes), static=True)
            self._static.add(path)
        self.stream.log(path, rr.Points2D(points.uv, class_ids=points.state, radii=1.5))

    def _meshes_due(self, frame: int) -> bool:
        return self.record.meshes_every > 0 and frame % self.record.meshes_every == 0

    def _log_params(self, kind: str, params: np.ndarray) -> None:
        """``metrics/params/<name>/<kind>`` for every named parameter of the model (unless ``record.parameters``
        is off)."""
        if not self.record.parameters:
            return
        for name, value in self.model.parameter_series(params).items():
            self._scalar(f"metrics/params/{name}/{kind}", value)

    def log_timings(self, frame: int, timings_ms: dict[str, float]) -> None:
        """``metrics/timing/<stage>_ms``; the tracker's own stages (``estimate_<stage>``) below ``estimate/``."""
        for stage, milliseconds in timings_ms.items():
            self._scalar(f"metrics/timing/{stage.replace('estimate_', 'estimate/', 1)}_ms", milliseconds, frame)

    def _scalar(self, entity: str, value: float, frame: int | None = None) -> None:
        """One value of the series at ``entity``, at ``frame`` (default: the frame being logged)."""
        frames, values = self._series.setdefault(entity, ([], []))
        frames.append(self._frames[-1] if frame is None else frame)
        values.append(float(value))

    def _log_series(self) -> None:
        """Every series as one column (without a wall-clock time per row, which took half a series' bytes), in a
        colour of its own among its plot's (`series_colors`)."""
        colours = series_colors(self._blueprint, list(self._series), self._series_names)
        for entity, (frames, values) in self._series.items():
            if entity in colours:
                self.stream.log(entity, rr.SeriesLines(colors=[colours[entity]], widths=[SERIES_WIDTH_PX]), static=True)
            self.stream.send_columns(
                entity, indexes=[rr.TimeColumn(TIMELINE, sequence=frames)], columns=rr.Scalars.columns(scalars=values)
            )

    def _log_videos(self) -> None:
        """Each view's video, and which of its frames each run frame shows."""
        for view, encoder in self._videos.items():
            if not encoder.frames:
                continue
            video = rr.AssetVideo(contents=encoder.finish(), media_type="video/mp4")
            entity = f"world/cameras/{view}/image/rgb"
            self.stream.log(entity, video, static=True)
            self.stream.send_columns(
                entity,
                indexes=[rr.TimeColumn(TIMELINE, sequence=self._frames)],
                columns=rr.VideoFrameReference.columns_nanos(video.read_frame_timestamps_nanos()),
            )

    def close(self) -> None:
        """Write the series and videos, then close the file (`RecordingFile.close`; idempotent)."""
        self._file.close(last_writes=self._log_last)

    def _log_last(self) -> None:
        self._log_series()
        self._log_videos()
