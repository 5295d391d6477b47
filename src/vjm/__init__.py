"""vjm: virtual-joint-method stiffness of parallel machines.

>>> import vjm
>>> m = vjm.load_model("data/orthoglide/puu.yaml")          # doctest: +SKIP
>>> r = m.stiffness([0.0, 0.0, 0.0]); r.k_tran, r.k_rot        # doctest: +SKIP
"""
from .errors import VjmError
from .model import Actuator, Joints, Link, Model
from .modelfile import load_model, save_model, with_links
from .stiffness import StiffnessResult

__all__ = ["VjmError", "Model", "Actuator", "Link", "Joints", "StiffnessResult",
           "load_model", "save_model", "with_links"]
