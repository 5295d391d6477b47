"""Running as a command or a library, for linkfea and vjm: error types (:mod:`.errors`), argument checks
(:mod:`.checks`), progress callbacks (:mod:`.progress`), memory and durations (:mod:`.memory`), Ctrl-C during
the mesher (:mod:`.child`), typer apps as commands (:mod:`.clirun`) and the shipped files (:mod:`.resources`)."""
