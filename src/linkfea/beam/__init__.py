"""Beams: closed forms (:mod:`.closed_form`), section constants (:mod:`.sections`), N-beam equivalents of a
CAD link (:mod:`.equivalents`) and the beam-versus-FEA comparison (:mod:`.compare`, :mod:`.comparison`,
:mod:`.metrics`, its report :mod:`.report`)."""
