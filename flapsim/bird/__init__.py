"""System 1: data-driven flapping flight of a collared dove (Ju et al., ACM TOG 2013)."""
