"""Kinematics: elementary transforms, serial chains and their Jacobians, per-pose kinematics, inverse kinematics."""
