"""Exceptions that carry a one-line, user-facing message naming the problem and the fix."""


class FlapsimError(Exception):
    """Base class: the CLI prints ``flapsim: error: <message>`` and exits with status 2."""


class ModelError(FlapsimError):
    """An MJCF model could not be loaded or lacks what a feature needs."""


class DataFileError(FlapsimError):
    """A data file (capture, database, path, config) is missing, corrupt or foreign."""


class InputError(FlapsimError):
    """An argument has the wrong shape, range or value (NaN, negative area, ...)."""


class SimulationError(FlapsimError):
    """A simulation diverged or produced non-finite state."""


class ProviderError(FlapsimError):
    """A passive-force provider raised while MuJoCo was stepping."""


class OutputError(FlapsimError, OSError):
    """The system refused to write an output (a full disk, a quota, a failed video encoder):
    the message names the file; nothing half-written is left (the CLI's exit status 1). An
    OSError too, as the failure it stands for was."""
