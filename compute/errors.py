"""Errors raised by the compute stage."""


class InputError(ValueError):
    """Input the toolkit cannot use; the message names the file (or folder), the field and what
    was expected."""

    def __init__(self, file, field: str, expected: str, got: object = None):
        self.file, self.field, self.expected, self.got = str(file), field, expected, got
        msg = f"{file}: field '{field}': expected {expected}"
        if got is not None:
            msg += f", got {got!r}"
        super().__init__(msg)


class SceneError(InputError):
    """A scene folder is missing, malformed or inconsistent."""


class OutputFolderError(InputError):
    """An output folder that cannot be used: not a folder, not writable, written by another
    compute, or holding files this version cannot resume from."""


class OutputWriteError(RuntimeError):
    """A file of the output folder could not be written: a full disk, a permission, a read-only
    file system. The message names the file and the operating system's reason; what was
    written before stays (compute.files writes whole files atomically)."""

    def __init__(self, file, reason: str):
        self.file, self.reason = str(file), reason
        super().__init__(f"{file}: could not be written: {reason}")


class SimulationError(RuntimeError):
    """A run went numerically wrong (NaN, inverted element, diverging solver).

    Raised after what was written so far has been flushed; the message is a diagnosis. A failed
    step's ``work`` (compute.stepping.step_stats.StepStats) is what its attempts spent.
    """

    work = None


class StepFailure(Exception):
    """A step attempt that must not be accepted (the message is the diagnosis): the step
    control cuts the step, and raises :class:`SimulationError` when cutting does not help.
    ``work`` (compute.stepping.step_stats.StepStats): what the attempt spent before it failed."""

    work = None
