"""Exceptions raised by MCAHRS, one per C status code (docs/ALGORITHMS.md section 4)."""

from __future__ import annotations


class McaError(Exception):
    """Base class of every MCAHRS error."""


class NullError(McaError):
    """A required pointer was NULL (a binding bug, never user input)."""


class BadDtError(McaError, ValueError):
    """Step length not finite, <= 0, or longer than the configured maximum."""


class NonFiniteError(McaError, ValueError):
    """An input value was NaN or infinite."""


class SingularError(McaError, ArithmeticError):
    """Innovation covariance not positive definite."""


class BadMaskError(McaError, ValueError):
    """Measurement mask empty or with unknown bits."""


class BadArgError(McaError, ValueError):
    """An argument outside its documented range."""


class BadConfigError(McaError, ValueError):
    """A configuration value outside its documented range."""


class TimeBackwardsError(McaError, ValueError):
    """A time stamp earlier than the last one accepted."""


class RangeError(McaError, ValueError):
    """Latitude/longitude/altitude out of range."""


class NotInitError(McaError, RuntimeError):
    """The filter has not been initialised yet."""
