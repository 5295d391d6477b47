"""The values every stage and vjm share: frames and the adjoint map (:mod:`.frames`), the checked 6x6
compliance (:mod:`.compliance`) and materials (:mod:`.materials`)."""
