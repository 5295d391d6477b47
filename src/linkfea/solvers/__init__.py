"""Linear algebra only (nothing of P2): factorizers of the reduced stiffness, direct (:mod:`.factorizers`)
and multigrid-preconditioned CG (:mod:`.iterative`), each returning a :class:`.factorization.Factorization`."""
