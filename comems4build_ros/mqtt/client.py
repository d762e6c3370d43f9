"""Broker connection (paho-mqtt): TLS, username/password, last will, reconnects, inbox.

:class:`MqttLink` runs paho's network loop in its own thread. Incoming messages go into
a thread-safe queue (:meth:`MqttLink.drain`) and an optional ``wake`` callback is called
for each, so a ROS node can process them on its own executor thread. On every
(re)connect the link subscribes its topics again and calls ``on_connect`` (the bridge
republishes its retained discovery and availability messages there: an embedded broker
that restarted has lost them). paho reconnects by itself with a back-off of at most
``reconnect_max_s``; publishes with QoS 1 or 2 made while the link is down are queued by
paho and sent after the reconnect.

The password comes from a file or an environment variable (``password_file`` /
``password_env`` of ``config/mqtt.yaml``) and is never logged or put into an error
message.
"""

from __future__ import annotations

import os
import queue
import ssl
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import paho.mqtt.client as paho

from comems4build_ros.files.errors import InputError
from comems4build_ros.mqtt.topicmap import BrokerParams

#: Shortest wait between reconnect attempts [s].
RECONNECT_MIN_S = 0.1


class BrokerConfigError(InputError):
    """Broker credentials or TLS files cannot be read (the message never holds the password)."""


@dataclass(frozen=True)
class Message:
    """One received message with its receive time [s, ``time.monotonic``]."""

    topic: str
    payload: bytes
    retain: bool
    t_recv: float


def read_password(settings: BrokerParams, environ: dict[str, str] | None = None) -> str | None:
    """The broker password from ``password_file`` (first line) or ``password_env``; None if neither.

    Raises
    ------
    BrokerConfigError
        If the file cannot be read or the variable is not set (named, never the value).
    """
    env = os.environ if environ is None else environ
    if settings.password_file:
        try:
            lines = Path(settings.password_file).read_text(encoding="utf-8").splitlines()
        except OSError as exc:
            raise BrokerConfigError(f"broker.password_file {settings.password_file}: cannot read: {exc.strerror}") \
                from None
        if not lines or not lines[0]:
            raise BrokerConfigError(f"broker.password_file {settings.password_file}: first line is empty")
        return lines[0]
    if settings.password_env:
        value = env.get(settings.password_env)
        if not value:
            raise BrokerConfigError(f"broker.password_env: environment variable {settings.password_env} is not set")
        return value
    return None


def tls_context(settings: BrokerParams) -> ssl.SSLContext:
    """TLS context for ``mqtts://``: the CA file (or the system's), optional client certificate."""
    try:
        ctx = ssl.create_default_context(cafile=settings.ca_file or None)
        if settings.cert_file:
            ctx.load_cert_chain(settings.cert_file, settings.key_file or None)
    except (OSError, ssl.SSLError) as exc:
        raise BrokerConfigError(f"broker TLS files (ca_file/cert_file/key_file): {exc}") from None
    if settings.tls_insecure:
        ctx.check_hostname = False
    return ctx


class MqttLink:
    """One paho client with a last will, resubscription on reconnect and an inbox.

    Parameters
    ----------
    settings : broker settings of the topic map
    client_id : MQTT client id (unique per broker)
    subscriptions : topics to (re)subscribe on every connect
    will : ``(topic, payload)`` of the last will (retained), e.g. availability ``offline``
    on_connect : called (in paho's thread) after every connect and resubscription
    wake : called (in paho's thread) after each message is queued
    """

    def __init__(
        self,
        settings: BrokerParams,
        client_id: str,
        subscriptions: Iterable[str] = (),
        will: tuple[str, str] | None = None,
        on_connect: Callable[[], None] | None = None,
        wake: Callable[[], None] | None = None,
    ) -> None:
        self.settings = settings
        self.subscriptions = list(subscriptions)
        self.inbox: queue.SimpleQueue[Message] = queue.SimpleQueue()
        self.connected = threading.Event()
        self.connects = 0  # successful connects (1 + reconnects)
        self.t_disconnected: float | None = None  # when the link was lost (time.monotonic; None = connected)
        self.disconnects = 0
        self.last_error = ""  # reason of the last refused connect or disconnect (never a password)
        self._pending_subs: set[int] = set()  # message ids of this connection's subscriptions not yet acknowledged
        self.t_subscribed: float | None = None  # when every subscription of this connection was acknowledged
        self._on_connect_cb = on_connect
        self._wake = wake
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=True)
        password = read_password(settings)
        if settings.username:
            self.client.username_pw_set(settings.username, password)
        if settings.tls:
            self.client.tls_set_context(tls_context(settings))
            if settings.tls_insecure:
                self.client.tls_insecure_set(True)
        if will is not None:
            self.client.will_set(will[0], will[1], qos=1, retain=True)
        self.client.reconnect_delay_set(RECONNECT_MIN_S, max(RECONNECT_MIN_S, settings.reconnect_max_s))
        self.client.max_queued_messages_set(0)  # unlimited queue while disconnected
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self.client.on_subscribe = self._on_subscribe

    # ------------------------------------------------------------------ paho callbacks
    def _on_connect(self, client: paho.Client, userdata: object, flags: object, reason: object, props: object) -> None:
        if getattr(reason, "is_failure", False):
            self.last_error = str(reason)  # e.g. "Not authorized"; paho retries
            return
        self.connects += 1
        self.t_disconnected = None
        self.t_subscribed = None
        self._pending_subs = set()
        for topic in self.subscriptions:
            result, mid = client.subscribe(topic, qos=self.settings.qos)
            if mid is not None:
                self._pending_subs.add(mid)
        if not self._pending_subs:
            self.t_subscribed = time.monotonic()
        self.connected.set()
        if self._on_connect_cb is not None:
            self._on_connect_cb()

    def _on_disconnect(self, client: paho.Client, userdata: object, flags: object, reason: object,
                       props: object) -> None:
        self.connected.clear()
        self.t_subscribed = None
        if self.t_disconnected is None:
            self.t_disconnected = time.monotonic()
        self.disconnects += 1
        self.last_error = str(reason)

    def _on_subscribe(self, client: paho.Client, userdata: object, mid: int, reasons: object, props: object) -> None:
        self._pending_subs.discard(mid)
        if not self._pending_subs and self.t_subscribed is None:
            self.t_subscribed = time.monotonic()  # the retained messages of every subscription follow its ack

    def _on_message(self, client: paho.Client, userdata: object, msg: paho.MQTTMessage) -> None:
        self.inbox.put(Message(msg.topic, bytes(msg.payload), bool(msg.retain), time.monotonic()))
        if self._wake is not None:
            self._wake()

    # ------------------------------------------------------------------ use
    def start(self, wait_s: float | None = None) -> bool:
        """Connect asynchronously and start the network thread; with ``wait_s`` wait for the connect.

        Returns whether the link is connected (always True without ``wait_s`` once paho
        accepted the address; it keeps retrying in the background).
        """
        self.client.connect_async(self.settings.host, self.settings.port, keepalive=self.settings.keepalive_s)
        self.client.loop_start()
        if wait_s is None:
            return True
        return self.connected.wait(wait_s)

    def describe(self) -> str:
        """The link's state in words, for messages: connected, or for how long not and why."""
        url = self.settings.url
        if self.connected.is_set():
            return f"broker {url}: connected"
        since = "" if self.t_disconnected is None else f" for {time.monotonic() - self.t_disconnected:.1f} s"
        why = f", last error: {self.last_error}" if self.last_error else ""
        never = "" if self.connects else " (never connected)"
        return f"broker {url}: not connected{since}{never}{why}; the broker is down or unreachable"

    def publish(self, topic: str, payload: bytes | str, retain: bool = False, qos: int | None = None) -> None:
        """Publish (queued by paho while disconnected for QoS > 0)."""
        self.client.publish(topic, payload, qos=self.settings.qos if qos is None else qos, retain=retain)

    def drain(self) -> list[Message]:
        """Every message received since the last call, in arrival order."""
        out = []
        while True:
            try:
                out.append(self.inbox.get_nowait())
            except queue.Empty:
                return out

    def stop(self, final: tuple[str, str] | None = None, timeout_s: float = 2.0) -> None:
        """Publish ``final`` (retained, e.g. availability ``offline``), disconnect, stop the thread."""
        if final is not None and self.connected.is_set():
            info = self.client.publish(final[0], final[1], qos=1, retain=True)
            try:
                info.wait_for_publish(timeout_s)
            except (RuntimeError, ValueError):
                pass
        self.client.disconnect()
        self.client.loop_stop()
