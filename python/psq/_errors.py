# SPDX-License-Identifier: Apache-2.0
"""psq's exceptions: one class per stable psq::Status code (format/include/psq/status.h)."""

from typing import Dict, Optional, Type

__all__ = [
    "Error", "IoError", "TruncatedError", "BadHeaderError", "BadValueError", "BadIndexError",
    "UnsupportedError", "LimitError", "UnknownFormatError", "UsageError", "InternalError",
    "BadSequenceError", "ChecksumError",
]


class Error(Exception):
    """An error reported by psq.

    Attributes:
        code: the stable numeric code (psq::ErrorCode; never renumbered).
        name: its stable name ("truncated", "bad_header", ...).
        message: the one-line message, without the place.
        offset: the byte offset in the input the error refers to, or None.
        line: the 1-based line of a text input, or None.
        file: the file (or "<memory>") the error is about, or None.
    """

    code: int = 0
    name: str = "error"

    def __init__(self, message: str, offset: Optional[int] = None, line: Optional[int] = None,
                 file: Optional[str] = None) -> None:
        super().__init__(message)
        self.message = message
        self.offset = offset
        self.line = line
        self.file = file

    def __str__(self) -> str:
        place = ""
        if self.line is not None:
            place = f"line {self.line}: "
        elif self.offset is not None:
            place = f"byte {self.offset}: "
        return (f"{self.file}: " if self.file else "") + place + self.message

    def __reduce__(self):  # picklable, for Dask and multiprocessing
        return (_rebuild, (self.code, self.message, self.offset, self.line, self.file))


class IoError(Error):
    """The operating system refused a read, write or open."""
    code, name = 1, "io"


class TruncatedError(Error):
    """The input ended before a structure was complete."""
    code, name = 2, "truncated"


class BadHeaderError(Error):
    """A header is missing, malformed or inconsistent."""
    code, name = 3, "bad_header"


class BadValueError(Error):
    """A value is malformed or not allowed (a NaN position, a corrupt record...)."""
    code, name = 4, "bad_value"


class BadIndexError(Error):
    """A vertex index is negative or out of range."""
    code, name = 5, "bad_index"


class UnsupportedError(Error):
    """Valid input that psq does not handle."""
    code, name = 6, "unsupported"


class LimitError(Error):
    """A size or count exceeds a documented limit."""
    code, name = 7, "limit"


class UnknownFormatError(Error):
    """The content matches no format psq reads."""
    code, name = 8, "unknown_format"


class UsageError(Error, ValueError):
    """The caller passed invalid arguments (also a ValueError)."""
    code, name = 9, "usage"


class InternalError(Error):
    """A psq bug: an invariant did not hold."""
    code, name = 10, "internal"


class BadSequenceError(Error):
    """Events that do not form a valid processing sequence."""
    code, name = 11, "bad_sequence"


class ChecksumError(Error):
    """Stored data does not match its checksum."""
    code, name = 12, "checksum"


_BY_CODE: Dict[int, Type[Error]] = {
    cls.code: cls for cls in (IoError, TruncatedError, BadHeaderError, BadValueError, BadIndexError,
                              UnsupportedError, LimitError, UnknownFormatError, UsageError,
                              InternalError, BadSequenceError, ChecksumError)
}


def _rebuild(code: int, message: str, offset, line, file) -> Error:
    return _from_status(code, message, offset, line, file)


def _from_status(code: int, message: str, offset=None, line=None, file=None) -> Error:
    """The exception for a psq::Status (called by the extension)."""
    cls = _BY_CODE.get(code, Error)
    err = cls(message, offset, line, file)
    if cls is Error:
        err.code = code
    return err
