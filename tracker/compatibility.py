"""Which tracker tracks which model, from how many camera views: one table (`FITS`), checked before every run
(`experiments.checks`: a combination not in it fails with one line) and shown in the README
(`python -m experiments.options`).

A tracker that is not in the table (a plugin's, until it calls `allow`) tracks any model from any rig. A fit
may name the rig to use when the composed one has too few or too many views (``model=body_mesh`` picks the
one-camera ``rig=body_side``; ``tracker=abis`` on the body then takes ``rig=body_multi_vga``), and settings the
combination needs where the composed config leaves them unset (AbIS tracks the body's textured skin:
``model.texture_seed``): the command line adds them unless it names them itself (`experiments.validate.with_picks`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Fit:
    """A tracker on a model: the camera views it uses (fewest, most), the rig option it takes when the composed
    rig has another number of views (None: it asks for one), and ``(key, value)`` settings it needs where the
    composed config leaves them null."""

    views: tuple[int, int]
    rig: str | None = None
    sets: tuple[tuple[str, Any], ...] = ()

    def allows(self, views: int) -> bool:
        return self.views[0] <= views <= self.views[1]

    @property
    def says(self) -> str:
        low, high = self.views
        return f"{low} camera view{'s' * (high > 1)}" if low == high else f"{low} to {high} camera views"


# tracker -> model -> fit
FITS: dict[str, dict[str, Fit]] = {
    "render_only": {"dsq_arm": Fit((1, 4)), "body_mesh": Fit((1, 4))},
    # paper 1: 3 orthogonal views; the body by the features of its textured skin, from 3 or 4 views at 640x480
    "abis": {"dsq_arm": Fit((1, 4)), "body_mesh": Fit((3, 4), rig="body_multi_vga", sets=(("model.texture_seed", 0),))},
    "tbf": {"body_mesh": Fit((1, 4)), "dsq_arm": Fit((1, 4))},  # paper 2: one camera; more: the views multiplied
}


def allow(tracker: str, model: str, fit: Fit) -> None:
    """Add a row: ``tracker`` tracks ``model`` as ``fit`` says (a plugin's tracker states its fits this way)."""
    FITS.setdefault(tracker, {})[model] = fit


def fit_of(tracker: str, model: str) -> Fit | None:
    """How ``tracker`` tracks ``model`` (None: the tracker is not in the table, any goes). Raises ``ValueError``
    with one line when it does not track that model."""
    if tracker not in FITS:
        return None
    fits = FITS[tracker]
    if model not in fits:
        raise ValueError(f"tracker={tracker} does not track model={model}: allowed model={'|'.join(fits)}")
    return fits[model]
