"""Errors raised for bad input: each message names the file or argument and the problem.

Besides the message, an error carries what failed as attributes (None where unknown), so that
programs need not parse messages:

- ``file``: the path (str) of the file that failed,
- ``element``: the part of it: a PLY element, or element and property as ``"vertex.x"``; an
  array, column, archive member or camera-file field name,
- ``row``: the first offending row (0-based index into that element or array),
- ``argument``: the API argument, option field or CLI flag that was rejected.

:func:`error_context` fills attributes that an inner raise site did not know (a loader knows its
file, the parser below it only the text)."""

from __future__ import annotations

import contextlib
import functools

#: The attributes an error or warning may carry, in the order of the constructors' keywords.
CONTEXT = ("file", "element", "row", "argument")


class SurfsplatError(Exception):
    """Base class of every error surfsplat raises on purpose.

    Keyword-only arguments (all optional, default None), kept as attributes of the same names:
    ``file`` (path of the failing file, stored as str), ``element`` (PLY element or property,
    array, column or member name), ``row`` (first offending row, int), ``argument`` (API argument,
    option field or CLI flag). The message (``str(error)``) is the positional text alone."""

    def __init__(self, *args, file=None, element=None, row=None, argument=None):
        super().__init__(*args)
        self.file = None if file is None else str(file)
        self.element = element
        self.row = None if row is None else int(row)
        self.argument = argument

    def context(self) -> dict:
        """The attributes that are set, as ``{name: value}``."""
        return {name: getattr(self, name) for name in CONTEXT if getattr(self, name, None) is not None}


class InputError(SurfsplatError, ValueError):
    """Input data (a file, an array, an argument) is malformed or unusable."""


class RenderError(SurfsplatError, RuntimeError):
    """The OpenGL renderer could not be created or a shader failed to build."""


class EmptyFrameWarning(UserWarning):
    """A rendered image shows nothing, or far less than the model's bounds cover: the camera most
    likely looks past the model (the message names the bounds and the camera)."""


def fill_context(error: BaseException, **context) -> BaseException:
    """Set the attributes of ``error`` (a SurfsplatError) given in ``context`` that it does not
    carry yet (None values are skipped; a value set at the raise site is kept); return ``error``."""
    if isinstance(error, SurfsplatError):
        for name, value in context.items():
            if name not in CONTEXT:
                raise TypeError(f"unknown error attribute {name!r}")
            if value is not None and getattr(error, name, None) is None:
                setattr(error, name, str(value) if name == "file" else value)
    return error


@contextlib.contextmanager
def error_context(**context):
    """Within the block, a SurfsplatError that passes through gets the attributes of ``context``
    (``file=``, ``element=``, ``row=``, ``argument=``) it does not carry yet
    (:func:`fill_context`); the error itself and its message are unchanged."""
    try:
        yield
    except SurfsplatError as exc:
        fill_context(exc, **context)
        raise


def file_reader(function):
    """Decorator of a function whose first argument is a file's path: a SurfsplatError raised
    while it runs gets ``file`` set to that path where the raise site left it unset."""

    @functools.wraps(function)
    def read(path, *args, **kwargs):
        with error_context(file=path):
            return function(path, *args, **kwargs)

    return read
