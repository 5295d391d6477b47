"""The immutable machine model (:mod:`~vjm.model.machine`) and its link springs (:mod:`~vjm.model.links`)."""
