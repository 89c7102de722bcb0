"""The one module that writes Rerun recordings: turns run results into entities of ``run.rrd``.

Entity paths (DESIGN.md): ``world/cameras/<view>`` (Transform3D + Pinhole, static),
``world/cameras/<view>/image/{rgb,labels}``, ``world/truth/<part>`` (Mesh3D), and time series
``metrics/params/<name>/truth`` (the model's `parameter_series`: ``<part>/<param>`` for the DSQ arm, root and
joint angles for the body), ``metrics/visible_px/<view>/<part>``, ``metrics/timing/<stage>_ms``; timeline
``frame``. Body scenes add ``capture/<view>/silhouette`` (the extracted silhouette), ``capture/<view>/weights/
{wxor,nwxor}`` (the weight maps d_P of paper 2's eq 8 and 9, float images) and
``metrics/silhouette_iou/<view>``. Each recording has its own ``recording_id`` and a default blueprint. The file
is written under a temporary name and renamed to its target by `RunRecording.close`, so a crashed run leaves no
partial ``run.rrd``.
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from tracker.abis.correspondences import COUNT_NAMES
from tracker.abis.tracker import FEATURE_STATES, AbisResult
from tracker.atomic import AtomicFile
from tracker.geometry.cameras import Camera
from tracker.models.body_mesh import BodyMesh
from tracker.observe.silhouettes import CapturedFrame
from tracker.sequence import FrameInput
from tracker.tbf.distances import weight_map
from tracker.tbf.evaluation import right_arm_swing_deg
from tracker.tbf.tracker import TbfResult

APPLICATION_ID = "articulated-tracking"
FEATURE_COLORS = {"tracked": (0, 220, 0), "new": (0, 160, 255), "discarded": (255, 40, 40), "unpaired": (150, 150, 150)}
TIMELINE = "frame"


def default_blueprint(view_names: Sequence[str], part_names: Sequence[str], silhouettes: bool = False,
                      weight_maps: bool = True) -> rrb.Blueprint:  # fmt: skip
    """Views with their label overlays on top (body scenes: with the silhouette, and the weight maps when they are
    recorded, beside them); the 3-D scene and the key time series below, the model's own first: the right arm's
    swing and the tree search for the body, the pair counts for the DSQ arm."""
    if silhouettes:
        series = [rrb.TimeSeriesView(name="right arm swing (deg)", origin="metrics/swing_deg"),
                  rrb.TimeSeriesView(name="tree search", origin="metrics/tree"),
                  rrb.TimeSeriesView(name="silhouette IoU", origin="metrics/silhouette_iou"),
                  rrb.TimeSeriesView(name="joint angles", origin="metrics/params/joints")]  # fmt: skip
        panes = [(None, "world/cameras", "/image"), ("silhouette", "capture", "/silhouette")]
        if weight_maps:
            panes += [("wXOR weights", "capture", "/weights/wxor"), ("nwXOR weights", "capture", "/weights/nwxor")]
        views = [rrb.Spatial2DView(name=f"{v} {name}" if name else v, origin=f"{root}/{v}{leaf}")
                 for v in view_names for name, root, leaf in panes]  # fmt: skip
    else:
        series = [rrb.TimeSeriesView(name="pairs", origin="metrics/correspondences"),
                  *(rrb.TimeSeriesView(name=f"{part} truth", origin=f"metrics/params/{part}") for part in part_names)]
        views = [rrb.Spatial2DView(name=v, origin=f"world/cameras/{v}/image") for v in view_names]
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(*views),
            rrb.Horizontal(
                rrb.Spatial3DView(name="3-D scene", origin="world"),
                rrb.Tabs(
                    *series,
                    rrb.TimeSeriesView(name="visible pixels", origin="metrics/visible_px"),
                    rrb.TimeSeriesView(name="timing (ms)", origin="metrics/timing"),
                ),
            ),
            row_shares=[1.0, 1.3],
        ),
        collapse_panels=True,
    )


class RunRecording:
    """A per-run Rerun recording written to ``path``. Use as a context manager, or call `close`."""

    def __init__(
        self,
        path: str | Path,
        *,
        cameras: Sequence[Camera],
        part_names: Sequence[str],
        part_colors: Sequence[Sequence[int]],
        jpeg_quality: int = 90,
        images: bool = True,
        silhouettes: bool = False,
        weight_maps: bool = True,
    ) -> None:
        self.path = Path(path)
        self.recording_id = str(uuid.uuid4())
        self.part_names = list(part_names)
        self.jpeg_quality = jpeg_quality
        self.images = images
        self.weight_maps = weight_maps
        self._file: AtomicFile | None = AtomicFile(self.path)
        self.stream = rr.RecordingStream(APPLICATION_ID, recording_id=self.recording_id)
        blueprint = default_blueprint([camera.name for camera in cameras], part_names, silhouettes,
                                      weight_maps and images)  # fmt: skip
        self.stream.save(self._file.temporary, default_blueprint=blueprint)
        self._log_static(cameras, part_colors)
        self._meshes_logged: set[str] = set()
        self._last_sample: int | None = None

    def __enter__(self) -> RunRecording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _log_static(self, cameras: Sequence[Camera], part_colors: Sequence[Sequence[int]]) -> None:
        log = self.stream.log
        log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        classes = [rr.AnnotationInfo(id=0, label="background", color=(0, 0, 0))]
        classes += [
            rr.AnnotationInfo(id=k + 1, label=name, color=tuple(color))
            for k, (name, color) in enumerate(zip(self.part_names, part_colors, strict=True))
        ]
        log("world", rr.AnnotationContext(classes), static=True)
        # Feature states (tracker.abis.tracker.FEATURE_STATES) for the features overlay of each view.
        states = [rr.AnnotationInfo(id=k, label=state, color=FEATURE_COLORS[state])
                  for k, state in enumerate(FEATURE_STATES)]  # fmt: skip
        for camera in cameras:
            log(f"world/cameras/{camera.name}/image/features", rr.AnnotationContext(states), static=True)
        for camera in cameras:
            log(f"world/cameras/{camera.name}", rr.Transform3D(translation=camera.position, mat3x3=camera.rotation),
                static=True)
            log(
                f"world/cameras/{camera.name}/image",
                rr.Pinhole(image_from_camera=camera.intrinsic_matrix, resolution=[camera.width, camera.height],
                           camera_xyz=rr.ViewCoordinates.RDF),
                static=True,
            )

    def log_frame(self, frame: FrameInput, model) -> None:
        """Images, truth meshes, truth parameters and label areas of one frame (timings: `log_timings`)."""
        self.stream.set_time(TIMELINE, sequence=frame.frame)
        log = self.stream.log
        for view, rendered in frame.views.items():
            image_path = f"world/cameras/{view}/image"
            if self.images:
                rgb = rr.Image(rendered.rgb)
                log(f"{image_path}/rgb", rgb.compress(jpeg_quality=self.jpeg_quality) if self.jpeg_quality else rgb)
                log(f"{image_path}/labels", rr.SegmentationImage(rendered.labels, opacity=0.35))
            for part, pixels in zip(self.part_names, frame.visible_px[view], strict=True):
                log(f"metrics/visible_px/{view}/{part}", rr.Scalars(float(pixels)))
        self._log_meshes("truth", frame.meshes)
        self._log_params("truth", model.parameter_series(frame.truth))
        if isinstance(model, BodyMesh):
            self.stream.log("metrics/swing_deg/truth", rr.Scalars(right_arm_swing_deg(model, frame.truth)))

    def log_capture(self, captured: CapturedFrame) -> None:
        """Body scenes: each view's extracted silhouette, its wXOR / nwXOR weight maps (eq 8-9 over the whole
        image), and its IoU against the render mask (call after `log_frame`)."""
        log = self.stream.log
        for view, silhouette in captured.silhouettes.items():
            if self.images:
                png = cv2.imencode(".png", silhouette.astype(np.uint8) * 255)[1].tobytes()  # ~2 KB, lossless
                log(f"capture/{view}/silhouette", rr.EncodedImage(contents=png, media_type="image/png"))
                if silhouette.any() and self.weight_maps:
                    for cost in ("wxor", "nwxor"):
                        log(f"capture/{view}/weights/{cost}", rr.Image(weight_map(cost, silhouette).astype(np.float32)))
            if view in captured.iou:
                log(f"metrics/silhouette_iou/{view}", rr.Scalars(captured.iou[view]))

    def log_estimate(self, result, model) -> None:
        """The tracker's estimate of a frame (call after `log_frame`)."""
        if isinstance(result, TbfResult):
            self._log_tbf(result, model)
        else:
            self._log_abis(result, model)

    def _log_tbf(self, result: TbfResult, model) -> None:
        """A TBF frame: the estimated body in 3-D, its parameters, the tree search's nodes evaluated and kept per
        level, the posterior's entropy and the right arm's angle."""
        log = self.stream.log
        sample = None if result.filter is None else result.filter.sample
        if sample is None or sample != self._last_sample:  # the estimate is a sample: log its mesh when it changes
            self._log_meshes("estimate", model.surface_meshes(result.estimate), rgba=(255, 255, 0, 120))
            self._last_sample = sample
        self._log_params("estimate", model.parameter_series(result.estimate))
        log("metrics/swing_deg/estimate", rr.Scalars(right_arm_swing_deg(model, result.estimate)))
        if result.filter is not None:
            for level, (evaluated, kept) in enumerate(zip(result.filter.nodes_evaluated, result.filter.nodes_kept,
                                                          strict=True), start=1):  # fmt: skip
                log(f"metrics/tree/level{level}/evaluated", rr.Scalars(float(evaluated)))
                log(f"metrics/tree/level{level}/kept", rr.Scalars(float(kept)))
            log("metrics/tree/entropy", rr.Scalars(result.filter.entropy))

    def _log_abis(self, result: AbisResult, model) -> None:
        """An AbIS frame: features by state and the estimate's visible samples over each view, the estimated
        meshes in 3-D, estimated parameters, pair counts and costs as series (call after `log_frame`)."""
        log = self.stream.log
        for view, seen in result.views.items():
            image_path = f"world/cameras/{view}/image"
            log(f"{image_path}/features", rr.Points2D(seen.features.points, class_ids=seen.feature_states, radii=1.5))
            log(f"{image_path}/estimate", rr.Points2D(seen.visible.uv, colors=[255, 255, 0], radii=0.6))
        self._log_meshes("estimate", model.surface_meshes(result.estimate), rgba=(255, 255, 0, 120))
        self._log_params("estimate", model.parameter_series(result.estimate))
        for k, part in enumerate(self.part_names):
            for index, count in enumerate(COUNT_NAMES):
                total = sum(int(counts[k, index]) for counts in result.counts.values())
                log(f"metrics/correspondences/{part}/{count}", rr.Scalars(float(total)))
            log(f"metrics/cost/{part}", rr.Scalars(float(result.cost[k])))

    def _log_meshes(self, kind: str, meshes, rgba: tuple[int, int, int, int] | None = None) -> None:
        """``world/<kind>/<part>``: faces and colour once (static), vertices every frame."""
        for mesh in meshes:
            path = f"world/{kind}/{mesh.key}"
            if path not in self._meshes_logged:
                colour = rgba if rgba is not None else (*mesh.color, 255)
                self.stream.log(path, rr.Mesh3D.from_fields(triangle_indices=mesh.faces, albedo_factor=colour),
                                static=True)  # fmt: skip
                self._meshes_logged.add(path)
            # Positions only: the viewer shades without normals, and a 961-frame body run stays ~50 MB.
            self.stream.log(path, rr.Mesh3D.from_fields(vertex_positions=mesh.vertices.astype(np.float32)))

    def _log_params(self, kind: str, series: dict[str, float]) -> None:
        """``metrics/params/<name>/<kind>`` for every named parameter."""
        for name, value in series.items():
            self.stream.log(f"metrics/params/{name}/{kind}", rr.Scalars(value))

    def log_timings(self, frame: int, timings_ms: dict[str, float]) -> None:
        self.stream.set_time(TIMELINE, sequence=frame)
        for stage, milliseconds in timings_ms.items():
            self.stream.log(f"metrics/timing/{stage}_ms", rr.Scalars(milliseconds))

    def close(self) -> None:
        """Flush, close the file and move it to ``path`` (idempotent)."""
        if self._file is None:
            return
        file, self._file = self._file, None
        self.stream.flush()
        self.stream.disconnect()
        file.commit()
