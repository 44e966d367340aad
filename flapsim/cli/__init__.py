"""The command line: :mod:`flapsim.cli.main` parses, each module of
:mod:`flapsim.cli.commands` calls the library and prints."""
