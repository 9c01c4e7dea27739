"""foldbot: a cloth-folding robot stack — simulated cell, perception, planning and control."""

__version__ = "0.1.0"
