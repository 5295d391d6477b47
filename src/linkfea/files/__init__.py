"""Writing the user's files, for linkfea and vjm: one file at a time (:mod:`.atomic`) and output sets that
are complete or untouched, with their ownership manifest (:mod:`.outputs`)."""
