"""Project exceptions.

Every error caused by bad input (wrong dtype or shape, unreadable file, malformed profile or map,
impossible parameter, an output that cannot be made) is a :class:`StcVisionError`. Its message
names the offending thing and what was expected; the CLI prints it as one line and exits with
code 2.
"""


class StcVisionError(Exception):
    """Base class of every error this project raises on purpose."""


class BadInputError(StcVisionError, ValueError):
    """An argument, array or file does not meet the documented contract."""


class MapError(BadInputError):
    """A board map file (text or PNG) is malformed."""


class ProfileError(BadInputError):
    """A calibration profile is missing a field, has a wrong type or unit, or cannot be read."""


class FileExistsRefusedError(StcVisionError):
    """Refused to overwrite a file the user made (pass ``--force`` to allow it)."""


class OutputError(StcVisionError):
    """An output file or folder cannot be made (a directory in the way, a parent that is a file,
    no permission, a full disk...)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) turned into an exception, so that ``finally`` blocks run and no
    temporary file is left behind."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def signal_in_chain(exc: BaseException | None) -> int | None:
    """The signal number of a Ctrl-C or :class:`Terminated` among ``exc``'s causes, else None.

    A signal that lands inside code which wraps what it raises (a dataclass's ``__set_name__``
    during an import turns it into a RuntimeError) still means the user stopped the run.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, KeyboardInterrupt):
            return exc.signum if isinstance(exc, Terminated) else 2
        exc = exc.__cause__ or exc.__context__
    return None
