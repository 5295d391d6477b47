"""Stiffness of a model at a pose: the linear bordered system, its batched linear algebra, the nonlinear equilibrium."""
