"""Paper reproductions built on vjm: the seed's Table 1."""
