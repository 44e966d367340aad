"""The command line: :mod:`flapsim.cli.main` parses, each module of
:mod:`flapsim.cli.commands` calls the library and prints."""

from flapsim.core.validate import guard_gl

# The command line chooses MUJOCO_GL before any of its modules imports mujoco (an unusable
# value must not break --help); importing flapsim itself changes no environment variable.
guard_gl()
