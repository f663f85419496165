"""Error types that carry user-facing, one-line-per-problem messages.

Every problem line names *where* (file, row, key), *what* is wrong and *how to fix it*, e.g.::

    data/rig/modes.csv:4: freq_Hz = -12.0 is not positive; natural frequencies are > 0 Hz, check the sign

Raise one error holding all problems found, not the first only.
"""

from __future__ import annotations


class JointidError(Exception):
    """Base class: a user-facing error made of one or more problem lines."""

    def __init__(self, problems: str | list[str]):
        if isinstance(problems, str):
            problems = [problems]
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))

    def __str__(self) -> str:  # one line per problem
        return "\n".join(self.problems)


class ConfigError(JointidError):
    """Invalid configuration (config.yaml or --config overrides)."""


class DataError(JointidError):
    """Invalid measured data (dataset folder, CSV, UFF)."""


class ModelError(JointidError):
    """The FE model cannot be built or solved as configured."""


class NumericalWarning(UserWarning):
    """A result was computed but deserves attention (bound hit, ill-conditioning, extrapolation)."""
