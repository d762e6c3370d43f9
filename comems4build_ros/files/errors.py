"""The one exception type of the input checks.

Every check of what a user gives (an option, a parameter file, a scenario, a topic map, an
output path, a peer's address) raises :class:`InputError` or a subclass of it, naming the
option, file, field or topic and the rule broken. The command line reports these, and only
these, as invalid input (exit code 2); any other exception is a defect of the program,
reported as an internal error with its traceback in a file (exit code 70, ``EX_SOFTWARE`` of
``sysexits.h``).

It derives from ``ValueError`` so that code catching a bad value keeps working; a plain
``ValueError`` (from pandas, numpy or a bug) is no input error.
"""

from __future__ import annotations


class InputError(ValueError):
    """Invalid input: the message names the option, file, field or topic and the rule broken."""
