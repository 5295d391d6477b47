"""Machine-level trade-offs: link designs combined in one machine, and the spread of its stiffness."""
