"""Perception: RGB-D Observation → ClothState (segmentation, corners, back-projection, overlays).

Never imports the simulator: everything here works from an Observation alone.
"""
