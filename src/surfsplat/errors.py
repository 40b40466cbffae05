"""Errors raised for bad input: each message names the file or argument and the problem."""


class SurfsplatError(Exception):
    """Base class of every error surfsplat raises on purpose."""


class InputError(SurfsplatError, ValueError):
    """Input data (a file, an array, an argument) is malformed or unusable."""


class RenderError(SurfsplatError, RuntimeError):
    """The OpenGL renderer could not be created or a shader failed to build."""


class EmptyFrameWarning(UserWarning):
    """A rendered image shows nothing, or far less than the model's bounds cover: the camera most
    likely looks past the model (the message names the bounds and the camera)."""
