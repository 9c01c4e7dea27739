"""Garments: parametric outlines turned into cloth meshes with named keypoints."""
