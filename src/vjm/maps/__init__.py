"""Stiffness maps over a workspace grid: the grid, the compiled per-pose kernel, the pictures."""
