"""Model files: YAML read (:mod:`~vjm.modelio.read`) and written (:mod:`~vjm.modelio.write`), machine descriptions, YAML as data."""
