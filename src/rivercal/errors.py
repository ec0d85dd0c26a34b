"""Exception hierarchy of rivercal.

Every error that rivercal raises on purpose derives from :class:`RivercalError`, so a caller can
catch everything rivercal-specific in one clause while still telling the kinds apart. Each error
carries a message that names what is wrong (a file, a field, a value, a time or a location).
"""

from __future__ import annotations

__all__ = [
    "CaseError",
    "EngineDivergedError",
    "FieldProblem",
    "ModelRunError",
    "OptionError",
    "RivercalError",
    "StructureOverlap",
]


class RivercalError(Exception):
    """Base class of every error raised by rivercal."""


class CaseError(RivercalError, ValueError):
    """A case (``case.toml`` and its time series) is invalid.

    Parameters
    ----------
    message
        What is wrong, in words.
    file
        The file in which the problem was found (``case.toml``, a CSV file), if known.
    field
        The dotted path of the offending field (``branches[2].from_node``), if known.
    """

    def __init__(self, message: str, *, file: str | None = None, field: str | None = None):
        self.file = file
        self.field = field
        self.reason = message
        where = ": ".join(part for part in (file, field) if part)
        super().__init__(f"{where}: {message}" if where else message)

    def __reduce__(self):  # keep the fields when the error crosses a process boundary
        return (_rebuild_case_error, (self.reason, self.file, self.field))


class FieldProblem(RivercalError, ValueError):
    """A rule of the network or case schema broken by one field.

    The schema's validators raise it (pydantic wraps a ``ValueError`` into its validation error);
    the case loader turns it into a :class:`CaseError` that names the file and the full path.

    Parameters
    ----------
    path
        Path of the field relative to the model that raises the problem, e.g.
        ``cross_sections[1].chainage``; empty for the model as a whole.
    reason
        What is wrong, in words.
    """

    def __init__(self, path: str, reason: str):
        self.path = path
        self.reason = reason
        super().__init__(f"{path}: {reason}" if path else reason)

    def __reduce__(self):  # keep the fields when the error crosses a process boundary
        return (FieldProblem, (self.path, self.reason))


class StructureOverlap(CaseError):
    """A structure whose segment of the grid would overlap that of the previous structure on its branch.

    Parameters
    ----------
    structure, previous
        The two structures (weirs, culverts or pumps: objects with an ``id`` and a ``chainage`` in m),
        ``previous`` being the one before ``structure`` along the branch.
    branch
        The branch id.
    structure_length
        The segment length each of them needs, m.
    """

    def __init__(self, structure, previous, branch: str = "", structure_length: float = float("nan")):
        self.structure = structure
        self.previous = previous
        self.branch = branch
        self.structure_length = structure_length
        gap = abs(structure.chainage - previous.chainage)
        super().__init__(
            f"structure {structure.id!r} at chainage {structure.chainage:g} m of branch {branch!r} is too close to "
            f"{previous.id!r} ({gap:g} m away): each structure needs its own segment of "
            f"engine.structure_length = {structure_length:g} m"
        )

    def __reduce__(self):  # keep the fields when the error crosses a process boundary
        return (StructureOverlap, (self.structure, self.previous, self.branch, self.structure_length))


class OptionError(RivercalError, ValueError):
    """A value given to a command is invalid: a command-line option, or an argument a workflow passes on.

    The message names the option and the value and says what is wrong, e.g.
    ``--window '2011-01-01/2011-01-08': lies outside the case period``.

    Parameters
    ----------
    message
        What is wrong, naming the option.
    option
        The option, e.g. ``--window`` (None when several are involved).
    """

    def __init__(self, message: str, *, option: str | None = None):
        self.option = option
        super().__init__(message)

    def __reduce__(self):  # keep the option when the error crosses a process boundary
        return (_rebuild_option_error, (str(self), self.option))


class ModelRunError(RivercalError):
    """A model run could not be completed (base class of engine failures)."""


class EngineDivergedError(ModelRunError):
    """The hydrodynamic engine produced a non-physical state.

    Parameters
    ----------
    time
        Simulated time (ISO 8601, UTC) at which the divergence was detected.
    location
        Human-readable location: branch id and chainage (m), or node id.
    detail
        What was detected (non-finite level, velocity above the limit, ...).
    """

    def __init__(self, time: str, location: str, detail: str):
        self.time = time
        self.location = location
        self.detail = detail
        super().__init__(f"engine diverged at {time} at {location}: {detail}")

    def __reduce__(self):  # keep the fields when the error crosses a process boundary
        return (EngineDivergedError, (self.time, self.location, self.detail))


def _rebuild_case_error(reason: str, file: str | None, field: str | None) -> CaseError:
    return CaseError(reason, file=file, field=field)


def _rebuild_option_error(message: str, option: str | None) -> OptionError:
    return OptionError(message, option=option)
