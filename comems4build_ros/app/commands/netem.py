"""The ``--netem`` argument of ``launch``: ``tc netem`` parameters checked before anything starts.

The launcher passes the text to ``tc qdisc add ... netem`` (iproute2, tc-netem(8)) and runs
without it, with a note, where the kernel lacks netem. So that a misspelt parameter is not
taken for a missing kernel module, the text is checked here against the grammar of
tc-netem(8)::

    limit PACKETS | delay TIME [JITTER [CORRELATION]] | distribution {uniform|normal|pareto|paretonormal}
    | loss [random] PERCENT [CORRELATION] | loss state P13 [P31 [P32 [P23 [P14]]]]
    | loss gemodel P [R [1-H [1-K]]] | ecn | corrupt PERCENT [CORRELATION]
    | duplicate PERCENT [CORRELATION] | reorder PERCENT [CORRELATION] [gap DISTANCE]
    | rate RATE [PACKETOVERHEAD [CELLSIZE [CELLOVERHEAD]]] | slot MIN_DELAY [MAX_DELAY]
    [packets N] [bytes N] | seed SEED
"""

from __future__ import annotations

import re
from collections.abc import Callable

from comems4build_ros.files.errors import InputError

#: tc time: a number with an optional unit (no unit: microseconds).
TIME_RE = re.compile(r"\d+(\.\d+)?(s|sec|secs|ms|msec|msecs|us|usec|usecs|ns|nsec|nsecs)?")
#: tc percentage: a number in 0..100 with an optional ``%``.
PERCENT_RE = re.compile(r"(\d+(\.\d+)?)%?")
#: tc rate: a number with a bit or byte unit (SI or IEC prefixes).
RATE_RE = re.compile(r"\d+(\.\d+)?([kmgt]i?)?(bit|bps)", re.IGNORECASE)
#: Delay distributions shipped with iproute2.
DISTRIBUTIONS = ("uniform", "normal", "pareto", "paretonormal")


class NetemError(InputError):
    """A ``--netem`` text that tc-netem(8) would refuse; the message names the parameter."""


def _percent(token: str) -> bool:
    m = PERCENT_RE.fullmatch(token)
    return bool(m) and float(m.group(1)) <= 100.0


def _integer(token: str) -> bool:
    return token.isdigit()


def _signed(token: str) -> bool:
    return token.lstrip("-").isdigit()


def _time(token: str) -> bool:
    return bool(TIME_RE.fullmatch(token))


def _rate(token: str) -> bool:
    return bool(RATE_RE.fullmatch(token))


def _distribution(token: str) -> bool:
    return token in DISTRIBUTIONS


#: Each parameter: (what its values are, for messages; required value kinds; optional value kinds).
GRAMMAR: dict[str, tuple[str, tuple[Callable[[str], bool], ...], tuple[Callable[[str], bool], ...]]] = {
    "limit": ("PACKETS", (_integer,), ()),
    "delay": ("TIME [JITTER [CORRELATION]], e.g. 5ms 1ms 25%", (_time,), (_time, _percent)),
    "distribution": (f"one of {', '.join(DISTRIBUTIONS)}", (_distribution,), ()),
    "loss": ("[random] PERCENT [CORRELATION], e.g. 1%", (_percent,), (_percent,)),
    "ecn": ("no value", (), ()),
    "corrupt": ("PERCENT [CORRELATION]", (_percent,), (_percent,)),
    "duplicate": ("PERCENT [CORRELATION]", (_percent,), (_percent,)),
    "reorder": ("PERCENT [CORRELATION]", (_percent,), (_percent,)),
    "gap": ("DISTANCE (packets, after reorder)", (_integer,), ()),
    "rate": ("RATE [PACKETOVERHEAD [CELLSIZE [CELLOVERHEAD]]], e.g. 10mbit", (_rate,), (_signed, _integer, _signed)),
    "slot": ("MIN_DELAY [MAX_DELAY], e.g. 1ms 5ms", (_time,), (_time,)),
    "packets": ("N (after slot)", (_integer,), ()),
    "bytes": ("N (after slot)", (_integer,), ()),
    "seed": ("SEED", (_integer,), ()),
}
#: Loss models with their own parameter lists: model -> (required percentages, optional percentages).
LOSS_MODELS = {"random": (1, 1), "state": (1, 4), "gemodel": (1, 3)}


def check_netem(text: str) -> str:
    """``text`` if tc-netem(8) accepts it as netem parameters, else :class:`NetemError` naming the parameter."""
    tokens = text.split()
    if not tokens:
        raise NetemError("no netem parameter given (e.g. 'delay 5ms loss 1%')")
    i = 0
    while i < len(tokens):
        key = tokens[i]
        if key not in GRAMMAR:
            raise NetemError(f"'{key}' is not a netem parameter ({', '.join(GRAMMAR)})")
        what, required, optional = GRAMMAR[key]
        i += 1
        if key == "loss" and i < len(tokens) and tokens[i] in LOSS_MODELS:
            n_req, n_opt = LOSS_MODELS[tokens[i]]
            i += 1
            required, optional = (_percent,) * n_req, (_percent,) * n_opt
        for kind in required:
            if i >= len(tokens) or not kind(tokens[i]):
                got = f"'{tokens[i]}'" if i < len(tokens) else "nothing"
                raise NetemError(f"'{key}' needs {what}; got {got}")
            i += 1
        for kind in optional:
            if i >= len(tokens) or tokens[i] in GRAMMAR or not kind(tokens[i]):
                break
            i += 1
    return text
