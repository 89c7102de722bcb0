"""Procedural textures for synthetic parts: blocks of random brightness, so images have corners to track."""

from __future__ import annotations

import numpy as np


def block_noise_texture(
    rng: np.random.Generator,
    cells: tuple[int, int],
    tint: tuple[int, int, int],
    px_per_cell: int = 8,
) -> np.ndarray:
    """An ``(cells[0] * px, cells[1] * px, 3)`` uint8 image of ``cells`` blocks, each a random shade of ``tint``.

    Rows run along the texture's v axis (a part's eta), columns along u (omega). Shades are drawn in [0.2, 1] so
    neighbouring blocks usually differ strongly: every block corner is a good Shi-Tomasi corner.
    """
    rows, cols = cells
    if rows < 1 or cols < 1 or px_per_cell < 1:
        raise ValueError(f"texture cells {cells} and px_per_cell {px_per_cell} must be positive")
    shades = rng.uniform(0.2, 1.0, size=(rows, cols))
    image = shades[:, :, None] * np.asarray(tint, dtype=np.float64)[None, None, :]
    image = np.repeat(np.repeat(image, px_per_cell, axis=0), px_per_cell, axis=1)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)
