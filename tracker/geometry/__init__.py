"""Geometry: rotations, rigid transforms, pinhole cameras and camera rigs."""
