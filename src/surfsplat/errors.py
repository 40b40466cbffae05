"""Errors raised for bad input: each message names the file or argument and the problem."""


class SurfsplatError(Exception):
    """Base class of every error surfsplat raises on purpose."""


class InputError(SurfsplatError, ValueError):
    """Input data (a file, an array, an argument) is malformed or unusable."""


class RenderError(SurfsplatError, RuntimeError):
    """The OpenGL renderer could not be created or a shader failed to build."""
