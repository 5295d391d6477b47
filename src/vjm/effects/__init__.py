"""The effect library: physical effects a stiffness model may leave out, each written once.

An effect (:class:`Effect`, registered with :func:`register`) carries its whole physics: the model it
changes or the twist it adds (``vjm diagnose``, ``vjm simulate``), and how it enters the nonlinear
equilibrium along a toolpath (``vjm path``).  :mod:`~vjm.effects.base` says what an effect is,
:mod:`~vjm.effects.library` holds the built-in ones, :mod:`~vjm.effects.modelops` the model edits and
per-pose quantities they use, :mod:`~vjm.effects.context` the data set they predict.

Adding an effect (docs/discrepancy.md)::

    from vjm.effects import Effect, Param, register

    @register
    class MyEffect(Effect):
        name = "my_effect"
        description = "one line saying what physical thing this is"
        kind = "additive"
        params = (Param("a", start=0.0, scale=1e-3, null=0.0, unit="mm"),)

        def extra(self, ctx, theta, C):
            return theta[0] * some_unit_twist(ctx)   # (n, 6)

It is then a candidate of ``vjm diagnose``, usable in ``vjm simulate --effect my_effect:a=0.002``, and
``vjm path`` applies the ``model_updated.yaml`` carrying it.

The effects of absolute-pose calibration (a robot's geometry, compliance ...; a parallel machine's offsets
and attachments) are :class:`~vjm.effects.absolute.PoseEffect` classes of :mod:`~vjm.effects.absolute`,
registered with :func:`~vjm.effects.absolute.register_pose` in their own registry (``absolute.POSES``):
fitted by the calibration engine with the instrument frames, they are no candidates of the deflection
diagnosis.
"""
from . import absolute as _absolute  # noqa: F401  (registers the absolute-pose effects)
from . import library as _library  # noqa: F401  (registers the built-in effects)
from .absolute import PoseEffect, register_pose
from .base import REGISTRY, Effect, Nonlinear, Param, check_values, get, register
from .context import Context

__all__ = ["REGISTRY", "Effect", "Nonlinear", "Param", "Context", "PoseEffect", "check_values", "get", "register",
           "register_pose"]
