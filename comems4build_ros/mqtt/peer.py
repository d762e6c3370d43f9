"""Run identity and peer authentication of the MQTT messages between ``mqtt_bridge`` and a house.

Two things keep a run's MQTT traffic its own (docs/real_building.md, "What is protected"):

* **Run id.** Every retained message the EMS side leaves on the broker (``<base>/step``,
  ``<base>/run``, ``<base>/state``) names its run (``"run": "<id>"``). A new run never
  takes another run's retained state as its own: the bridge clears a retained step, run
  or state message of another run (an empty retained payload deletes it, MQTT 3.1.1
  section 3.3.1.3) and names it on ``plant/events``; the simulated house ignores step and
  run messages of another run. A broker with persistence (Mosquitto's ``persistence
  true``, as Home Assistant's add-on runs it) keeps retained messages across its
  restarts, so a cut run's messages stay there until the next run clears them.
* **Authentication code.** With a peer key (the launcher's per-run secret, in a file of
  mode 0600 that only the run's user can read), every step-tagged message between the
  bridge and the house ends in ``"mac": "<hex>"``: the first :data:`MAC_HEX` hex digits
  of HMAC-SHA256 under the key of the topic and the payload before the code. The payload
  names the run and the step, so a message seen on the broker authorises nothing but
  itself: another step, another run or other values need the key. A message without a
  valid code, or of another run, is *foreign*: counted, reported and not applied.

No rclpy here (the ``mqtt`` layer); :func:`seal` and :func:`open_sealed` are pure functions
of bytes.
"""

from __future__ import annotations

import hmac
import json
import re
import secrets
from dataclasses import dataclass
from pathlib import Path

from comems4build_ros.files.errors import InputError
from comems4build_ros.wire.tokens import read_token_file

#: Hex digits of the authentication code (64 bits).
MAC_HEX = 16
#: Key of the run id in the EMS's JSON payloads.
RUN_KEY = "run"
#: Key of the authentication code: always the last member of a sealed JSON object.
MAC_KEY = "mac"
_SUFFIX = re.compile(rb', "' + MAC_KEY.encode() + rb'": "([0-9a-f]{' + str(MAC_HEX).encode() + rb'})"\}\s*$')
#: Characters of a run id (it stands in topics' payloads and log lines).
RUN_ID_PATTERN = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


class ForeignMessageError(ValueError):
    """A message that does not come from the run's peer; the text says why (never the key)."""


def new_run_id() -> str:
    """A fresh run id: 12 random hex digits (one per launch, or per bridge started by hand)."""
    return secrets.token_hex(6)


def check_run_id(run_id: str) -> str:
    """``run_id`` if it is 1..64 characters of ``A-Z a-z 0-9 _ . -``.

    Raises
    ------
    ValueError
        Naming the id.
    """
    if not RUN_ID_PATTERN.match(run_id):
        raise InputError(f"run id {run_id!r}: 1 to 64 characters of A-Z, a-z, 0-9, '_', '.', '-'")
    return run_id


def read_peer_key(path: str | Path) -> bytes:
    """The peer key of a run secret file (:func:`comems4build_ros.wire.tokens.read_token_file`:
    mode 0600, an integer); the HMAC key is its decimal text prefixed with ``mqtt:``, so the
    same secret never keys the commands' codes and the MQTT codes alike.

    Raises
    ------
    ValueError
        Naming the file (unreadable, readable by others, not a token).
    """
    return b"mqtt:" + str(read_token_file(path)).encode("ascii")


def _code(key: bytes, topic: str, body: bytes) -> str:
    return hmac.new(key, topic.encode("utf-8") + b"\n" + body, "sha256").hexdigest()[:MAC_HEX]


def seal(key: bytes | None, topic: str, payload: bytes) -> bytes:
    """``payload`` (the text of a non-empty JSON object) with the authentication code appended
    as its last member (the code covers the topic and the payload as sent, up to the code);
    unchanged without a key.

    Raises
    ------
    ValueError
        If ``payload`` is not the text of a JSON object ending in ``}``.
    """
    if key is None:
        return payload
    text = payload.rstrip()
    inner = text[:-1].rstrip()
    if not text.startswith(b"{") or not text.endswith(b"}") or inner == b"{":
        raise ValueError(f"topic '{topic}': only a non-empty JSON object can be sealed")
    return inner + f', "{MAC_KEY}": "{_code(key, topic, inner + b"}")}"}}'.encode()


def open_sealed(key: bytes | None, topic: str, payload: bytes) -> bytes:
    """The payload without its code, after checking the code; ``payload`` as is without a key.

    Raises
    ------
    ForeignMessageError
        If the payload has no code or a wrong one (the text names the topic).
    """
    if key is None:
        return payload
    m = _SUFFIX.search(payload)
    if m is None:
        raise ForeignMessageError(f"topic '{topic}': no authentication code")
    body = payload[:m.start()] + b"}"
    if not hmac.compare_digest(m.group(1).decode(), _code(key, topic, body)):
        raise ForeignMessageError(f"topic '{topic}': wrong authentication code")
    return body


@dataclass(frozen=True)
class RunMessage:
    """A decoded ``<base>/run`` or ``<base>/step`` payload of the EMS side."""

    run: str | None
    body: dict[str, object]


def parse_run_json(topic: str, payload: bytes) -> RunMessage:
    """The run id and the members of a run-tagged JSON payload (a payload without a run id,
    e.g. a plain step number of an older release, has ``run`` None).

    Raises
    ------
    ValueError
        If the payload is not a JSON object.
    """
    try:
        obj = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        obj = None
    if not isinstance(obj, dict):
        raise ValueError(f"topic '{topic}': not a JSON object: {payload[:60]!r}")
    run = obj.get(RUN_KEY)
    return RunMessage(run if isinstance(run, str) else None, obj)


def with_run(payload: bytes, run_id: str | None) -> bytes:
    """A JSON object's text with ``"run": "<run_id>"`` as its last member (unchanged without
    an id, or for a payload that is not a JSON object's text: a real device's plain number)."""
    text = payload.rstrip()
    if not run_id or not text.startswith(b"{") or not text.endswith(b"}"):
        return payload
    inner = text[:-1].rstrip()
    sep = b"" if inner == b"{" else b", "
    return inner + sep + f'"{RUN_KEY}": "{run_id}"}}'.encode()


class Peer:
    """This side's view of the run's peer: the run id, the peer key and the foreign messages.

    Parameters
    ----------
    run_id : the run's id (None: adopt the first live run message's, see :meth:`adopt`)
    key : peer key (:func:`read_peer_key`) or None (no authentication: a real building)
    """

    def __init__(self, run_id: str | None, key: bytes | None) -> None:
        self.run_id = run_id
        self.key = key
        self.foreign: dict[str, int] = {}  # reason -> messages not applied

    @property
    def foreign_total(self) -> int:
        """Foreign messages so far."""
        return sum(self.foreign.values())

    def wrap(self, topic: str, payload: bytes) -> bytes:
        """``payload`` tagged with the run id and sealed (:func:`seal`) for ``topic``."""
        return seal(self.key, topic, with_run(payload, self.run_id))

    def unwrap(self, topic: str, payload: bytes) -> bytes:
        """The payload of the peer without its code.

        With a key the code must be valid and the run id this run's; without a key a
        payload that names another run is foreign too (a payload without a run id, as a
        real device sends, is accepted).

        Raises
        ------
        ForeignMessageError
            Saying why; the reason is counted in :attr:`foreign`.
        """
        try:
            body = open_sealed(self.key, topic, payload)
            run = _run_of(body)
            if self.key is not None and run is None:
                raise ForeignMessageError(f"topic '{topic}': no run id")
            if run is not None and self.run_id is not None and run != self.run_id:
                raise ForeignMessageError(f"topic '{topic}': message of run '{run}', not of this run '{self.run_id}'")
        except ForeignMessageError as exc:
            reason = str(exc).split(": ", 1)[-1]
            reason = "another run" if reason.startswith("message of run") else reason
            self.foreign[reason] = self.foreign.get(reason, 0) + 1
            raise
        return body

    def adopt(self, run_id: str) -> None:
        """Take ``run_id`` as the run's id (a house started without one, on the bridge's live run message)."""
        self.run_id = check_run_id(run_id)


def _run_of(body: bytes) -> str | None:
    text = body.strip()
    if not text.startswith(b"{"):
        return None
    try:
        obj = json.loads(text.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    run = obj.get(RUN_KEY) if isinstance(obj, dict) else None
    return run if isinstance(run, str) else None
