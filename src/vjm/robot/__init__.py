"""Serial and tree robots: URDF and DH models, joint-space stiffness, self-weight.

>>> import vjm
>>> m = vjm.load_model("robots/ur10/ur10.yaml")
>>> r = m.stiffness([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])   # one configuration q (rad)
>>> int(r.rank), r.K.shape
(6, (6, 6))
"""
from .model import JointSpring, Payload, PlacedSpring, RobotModel

__all__ = ["RobotModel", "JointSpring", "PlacedSpring", "Payload"]
