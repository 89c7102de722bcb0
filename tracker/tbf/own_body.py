"""The tracker's own body model (paper 2, section 7): not the subject's, which it does not know, but MakeHuman's
base mesh or the standard body nearest the subject's stature and chest girth, measured on the subject as a tailor
would (`TbfSettings.body`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from tracker.models.body_mesh import BodyMesh
from tracker.models.body_shapes import standard_shape
from tracker.models.makehuman import body_measurements, build_body, nearest_standard_body


def own_body(
    subject: BodyMesh, choice: Literal["base", "nearest_standard"], triangles: int, cache_dir: str | Path | None = None
) -> tuple[BodyMesh, dict[str, Any]]:
    """The body the tracker models ``subject`` by, at ``triangles``, and which it is with both measured (for the
    run's metrics: its name, stature and chest girth, and the subject's); the standard bodies' measurements kept in
    ``cache_dir``."""
    measured = body_measurements(subject)
    name = nearest_standard_body(subject, triangles, cache_dir) if choice == "nearest_standard" else "base"
    body = build_body(triangles=triangles, shape=standard_shape(name))
    chosen = body_measurements(body)
    return body, {
        "name": name,
        "stature_m": round(chosen.stature_m, 4),
        "chest_girth_m": round(chosen.chest_girth_m, 4),
        "subject_stature_m": round(measured.stature_m, 4),
        "subject_chest_girth_m": round(measured.chest_girth_m, 4),
    }
