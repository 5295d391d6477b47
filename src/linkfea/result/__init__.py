"""The link result: :class:`.linkresult.LinkResult`, its typed records (:mod:`.records`), its JSON
(:mod:`.schema`: the schema and the one reader) and its file set on disk (:mod:`.fileset`, pictures :mod:`.post`)."""
