"""One module per CLI command (see :mod:`flapsim.cli.main`)."""
