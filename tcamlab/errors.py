"""tcamlab's own exception types.

Every error a user can cause carries a one-line message naming where the
problem is (file, row, column or key) and a hint, so the CLI can print it
without a traceback and exit with status 2.
"""

from __future__ import annotations


class TcamlabError(Exception):
    """Base class of every error tcamlab raises on purpose.

    Parameters
    ----------
    message : str
        What went wrong and where (file, row, column or key).
    hint : str, optional
        What the user can do about it.
    """

    exit_code = 2

    def __init__(self, message: str, hint: str | None = None):
        self.message = message
        self.hint = hint
        super().__init__(self.one_line())

    def one_line(self) -> str:
        text = self.message
        if self.hint:
            text += f" (hint: {self.hint})"
        return " ".join(text.split())


class InputError(TcamlabError):
    """A CSV log cannot be read or fails validation."""


class ConfigError(TcamlabError):
    """An experiment file is malformed or describes an impossible sample."""


class ModelDomainError(TcamlabError):
    """Inputs lie outside the range where a model is physically valid."""


class ConvergenceError(TcamlabError):
    """A root solve did not converge within its iteration limit."""


class IntegrationError(TcamlabError):
    """An ODE integration failed (non-finite state, step-size collapse)."""
