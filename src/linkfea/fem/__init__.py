"""The FEA stage: P2 linear elasticity of a meshed link under the 6 unit wrenches (:mod:`.problem`), the
rigid fit of its compliance (:mod:`.fit`), and what the result is worth (:mod:`.estimate`, :mod:`.convergence`)."""
