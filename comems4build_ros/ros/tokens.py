"""Run tokens of ``ems/command``: which EMS a command comes from (no rclpy here).

Every command carries, as its last element, the token of the EMS that sent it.
``plant_sim`` applies the commands of one token only (parameter ``ems_token``, or the
token of the run's first valid command) and counts every other command as foreign, so a
second node publishing in-range commands on the same topic cannot steer the plant.
The launcher draws one token per building and gives it to that building's EMS and plant;
an EMS started by hand without ``run_token`` derives one from its node name, so a
restarted EMS keeps its token.
"""

from __future__ import annotations

import secrets
import zlib

#: Tokens are integers in 1 .. MAX_TOKEN - 1 (exact in float64).
MAX_TOKEN = 2**53


def default_token(fully_qualified_name: str) -> int:
    """Token of an EMS started without one: CRC-32 of its fully qualified node name + 1."""
    return zlib.crc32(fully_qualified_name.encode("utf-8")) + 1


def new_token() -> int:
    """A random token for one building of a launch (1 .. 2^48)."""
    return secrets.randbelow(2**48) + 1
