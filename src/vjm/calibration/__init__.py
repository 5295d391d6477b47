"""Absolute-pose calibration of robots and parallel machines: the pose data and their column maps, the two
measurement models (a serial chain, :mod:`~vjm.calibration.serial`; a parallel machine by forward kinematics,
:mod:`~vjm.calibration.parallel`), the registration, the staged fit, write-back and the report."""
