"""Models: deformable superquadrics, the articulated tree shared by every model, the DSQ arm."""
