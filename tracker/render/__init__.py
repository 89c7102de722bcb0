"""Off-screen rendering of the synthetic scenes (pyrender through OSMesa). pyrender is imported lazily."""
