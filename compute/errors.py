"""Errors raised by the compute stage."""


class SceneError(ValueError):
    """A scene folder is missing, malformed or inconsistent.

    The message names the file, the field and what was expected.
    """

    def __init__(self, file, field: str, expected: str, got: object = None):
        self.file, self.field, self.expected = str(file), field, expected
        msg = f"{file}: field '{field}': expected {expected}"
        if got is not None:
            msg += f", got {got!r}"
        super().__init__(msg)


class SimulationError(RuntimeError):
    """A run went numerically wrong (NaN, inverted element, diverging solver).

    Raised after what was written so far has been flushed; the message is a diagnosis.
    """


class StepFailure(Exception):
    """A step attempt that must not be accepted (the message is the diagnosis): the step
    control cuts the step, and raises :class:`SimulationError` when cutting does not help."""
