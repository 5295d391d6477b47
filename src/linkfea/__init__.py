"""linkfea: a link CAD to its 6x6 compliance by finite elements."""
