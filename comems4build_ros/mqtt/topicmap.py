"""Topic map of the MQTT bridge (``config/mqtt.yaml``): topics, units, scaling, limits.

A value travels between the plant's units (the "SI" side: degC, l, W, fractions) and the
device's units on MQTT as ``si = mqtt * scale + offset``. The conversion runs in decimal
arithmetic on the payload text: with power-of-ten scales (%, kW) and decimal offsets a
value sent by one side and read by the other comes back to the last bit, which lets the
closed loop over MQTT reproduce the in-process run exactly.

Payloads are a plain decimal number (Home Assistant's default; ``1_000``, digits of other
scripts, ``nan`` or ``inf`` are refused, :func:`~comems4build_ros.files.inputs.parse_decimal`)
or a JSON object (``json_key``),
optionally with a step counter (``step_key``) used by the lock-step clock.
"""

from __future__ import annotations

import json
import math
from decimal import Decimal, InvalidOperation, localcontext
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from pydantic import Field, field_validator, model_validator

from comems4build_ros.core.config import ConfigError, PlantParams, Section, config_dir, parse_model, read_ros_params
from comems4build_ros.core.types import HP_DHW, HP_OFF, HP_SH
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import ASCII_SPACE, parse_decimal, parse_integer

#: Measurements the bridge knows: SI name -> meaning [unit]. The first four are required.
MEASUREMENTS: dict[str, str] = {
    "t_air_c": "indoor air temperature [degC]",
    "v_dhw_l": "usable hot-water volume at T_DHW [l]",
    "soc": "battery state of charge [-]",
    "loh": "level of hydrogen [-]",
    "hp_mod": "heat-pump modulation applied in the last step [-]",
    "fc_on": "fuel cell running in the last step [0/1]",
    "t_wall_in_c": "inner wall node temperature of the 4R3C model [degC]",
    "t_wall_out_c": "outer wall node temperature of the 4R3C model [degC]",
    "p_pv_w": "PV AC output [W]",
    "p_load_w": "appliance load [W]",
    "t_amb_c": "outdoor air temperature [degC]",
}
REQUIRED_MEASUREMENTS = ("t_air_c", "v_dhw_l", "soc", "loh")
#: Set-points, in the order of the ``ems/command`` layout (``types.Action`` fields).
SETPOINTS = ("hp_mod", "hp_mode", "p_fc_w", "p_bess_w")
#: Decimal precision of the unit conversion [digits]: enough for a float64 (17 significant digits,
#: exponents down to 1e-324) next to an offset, so that conversions are exact.
DECIMAL_PRECISION = 400
TRUE_WORDS = frozenset({"on", "true", "yes"})
FALSE_WORDS = frozenset({"off", "false", "no"})


class PayloadError(InputError):
    """An MQTT payload cannot be read; the message names the topic."""


class _Model(Section):
    """A topic-map section: the parameter rule of :class:`~comems4build_ros.core.config.Section`."""


def plain_topic(v: str) -> str:
    """``v`` if it is a plain MQTT topic: no wildcard (``+``, ``#``: a subscription to it would take every
    house's messages, a publication is refused by brokers), no leading or trailing ``/``, no empty level."""
    if not v or any(c in v for c in "+#") or v.startswith("/") or v.endswith("/") or "//" in v:
        raise InputError(f"'{v}' is not a plain MQTT topic (no wildcards '+' or '#', no empty level, no leading "
                         "or trailing '/')")
    return v


#: Shortest time of the topic map's durations [s]: a message's way through the broker (milliseconds)
#: and a house's measurement period (a second or more) make anything shorter meaningless.
MIN_DURATION_S = 0.1


class _Scaled(_Model):
    topic: str = Field(min_length=1)
    unit: str = ""
    scale: float = 1.0
    offset: float = 0.0
    json_key: str = ""
    step_key: str = ""

    @field_validator("scale")
    @classmethod
    def _nonzero(cls, v: float) -> float:
        if v == 0 or not math.isfinite(v):
            raise ValueError("must be finite and non-zero")
        return v

    @field_validator("topic")
    @classmethod
    def _no_wildcards(cls, v: str) -> str:
        return plain_topic(v)

    # -- codec -------------------------------------------------------------------
    def to_si(self, text: str) -> float:
        """SI value of the device value ``text`` (``si = mqtt * scale + offset``, decimal)."""
        parse_decimal(text)  # a plain decimal, as devices and Home Assistant write it (ValueError)
        with localcontext() as ctx:
            ctx.prec = DECIMAL_PRECISION
            d = Decimal(text.strip(ASCII_SPACE))
            if self.scale != 1.0 or self.offset != 0.0:
                d = d * Decimal(repr(self.scale)) + Decimal(repr(self.offset))
            return float(d)

    def from_si(self, value: float) -> str:
        """Device value text of the SI ``value`` (``(si - offset) / scale``, decimal)."""
        if self.scale == 1.0 and self.offset == 0.0:
            return repr(float(value))
        with localcontext() as ctx:
            ctx.prec = DECIMAL_PRECISION
            d = (Decimal(repr(float(value))) - Decimal(repr(self.offset))) / Decimal(repr(self.scale))
            text = format(d.normalize(), "f")
        return text if text not in ("-0",) else "0"

    def encode_text(self, text: str, step: int | None, raw_json: Any = None) -> bytes:
        """Payload carrying the device value ``text`` (a number, or ``raw_json`` if given)."""
        if not self.json_key:
            return text.encode()
        body = f'{{"{self.json_key}": {text if raw_json is None else json.dumps(raw_json)}'
        if self.step_key and step is not None:
            body += f', "{self.step_key}": {int(step)}'
        return (body + "}").encode()

    def _value_text(self, payload: bytes) -> tuple[Any, int | None]:
        """The value (text or JSON scalar) and step tag of a payload."""
        try:
            text = payload.decode("utf-8").strip(ASCII_SPACE)
        except UnicodeDecodeError:
            raise PayloadError(f"topic '{self.topic}': payload is not UTF-8") from None
        if not self.json_key:
            return text, None
        try:
            obj = json.loads(text, parse_float=str, parse_int=str)
        except json.JSONDecodeError as exc:
            raise PayloadError(f"topic '{self.topic}': payload is not JSON ({exc.msg}): {text[:80]!r}") from None
        if not isinstance(obj, dict) or self.json_key not in obj:
            raise PayloadError(f"topic '{self.topic}': JSON payload has no key '{self.json_key}': {text[:80]!r}")
        step = None
        if self.step_key and self.step_key in obj:
            try:
                step = parse_integer(str(obj[self.step_key]))
            except ValueError:
                raise PayloadError(f"topic '{self.topic}': step '{obj[self.step_key]}' is not an integer") from None
        return obj[self.json_key], step


class MeasurementSpec(_Scaled):
    """One house measurement on MQTT (``range`` and ``max_age_s`` feed the watchdog)."""

    range: tuple[float, float]
    max_age_s: float | None = Field(default=None, ge=MIN_DURATION_S)
    required: bool = True

    @field_validator("range")
    @classmethod
    def _ordered(cls, v: tuple[float, float]) -> tuple[float, float]:
        if not v[0] < v[1]:
            raise ValueError(f"must be [low, high] with low < high, got {list(v)}")
        return v

    def decode(self, payload: bytes) -> tuple[float, int | None]:
        """``(SI value, step tag or None)`` of a payload; ON/OFF/true/false read as 1/0.

        Raises
        ------
        PayloadError
            Naming the topic, for a payload that is not a number (or not the configured
            JSON object).
        """
        value, step = self._value_text(payload)
        if isinstance(value, bool):
            return (1.0 if value else 0.0), step
        text = str(value).strip(ASCII_SPACE)
        if text.lower() in TRUE_WORDS:
            return 1.0, step
        if text.lower() in FALSE_WORDS:
            return 0.0, step
        try:
            return self.to_si(text), step
        except (InvalidOperation, ValueError):
            raise PayloadError(f"topic '{self.topic}': {text[:40]!r} is not a number") from None

    def encode(self, value: float, step: int | None = None) -> bytes:
        """Payload of the SI ``value`` (the simulated house publishes with it)."""
        return self.encode_text(self.from_si(value), step)


class SetpointSpec(_Scaled):
    """One device set-point on MQTT, with its device limits and ramp limit (SI side)."""

    limits: tuple[float, float] | tuple[()] = ()
    max_change_per_step: float = Field(default=0.0, ge=0)
    values: dict[str, str] = Field(default_factory=dict)  # hp_mode: "0" -> "off" ...

    @field_validator("limits")
    @classmethod
    def _ordered(cls, v: tuple[float, float] | tuple[()]) -> tuple[float, float] | tuple[()]:
        if v and not v[0] < v[1]:
            raise ValueError(f"must be [low, high] with low < high, got {list(v)} (inverted or empty)")
        return v

    def encode(self, value: float, step: int | None = None) -> bytes:
        """Payload of the SI ``value`` (a mapped word if ``values`` is set)."""
        if self.values:
            word = self.values[str(int(value))]
            return self.encode_text("", step, raw_json=word) if self.json_key else word.encode()
        return self.encode_text(self.from_si(value), step)

    def decode(self, payload: bytes) -> tuple[float, int | None]:
        """``(SI value, step tag or None)``; a mapped word back to its number."""
        value, step = self._value_text(payload)
        text = str(value).strip(ASCII_SPACE)
        if self.values:
            for number, word in self.values.items():
                if text == word:
                    return float(number), step
            raise PayloadError(f"topic '{self.topic}': {text[:40]!r} is not one of {sorted(self.values.values())}")
        try:
            return self.to_si(text), step
        except (InvalidOperation, ValueError):
            raise PayloadError(f"topic '{self.topic}': {text[:40]!r} is not a number") from None


#: Largest TCP port number.
PORT_MAX = 65535


def check_broker_url(url: str) -> str:
    """``url`` if it is ``mqtt://host[:port]`` or ``mqtts://host[:port]`` with a port in 1..65535.

    The one rule for a broker address wherever it enters (``launch --broker``, a topic
    map's ``broker.url``). Credentials in the URL (``user:password@``) are refused: they
    would stand on command lines and in files; the topic map names a password file or
    variable instead.

    Raises
    ------
    ValueError
        Saying what is wrong with ``url``.
    """
    parts = urlsplit(str(url))
    if parts.scheme not in ("mqtt", "mqtts") or not parts.netloc or parts.path not in ("", "/") or \
            parts.query or parts.fragment or any(c.isspace() for c in str(url)):
        raise InputError(f"'{url}' is not mqtt://host[:port] or mqtts://host[:port]")
    if "@" in parts.netloc:
        raise InputError(f"'{parts.scheme}://...@{parts.hostname}': no credentials in the URL (the topic map's "
                         "broker.username with password_file or password_env)")
    try:
        port = parts.port
    except ValueError:
        port = -1
    if not parts.hostname or (port is not None and not 1 <= port <= PORT_MAX):
        what = "no host" if not parts.hostname else \
            f"port {parts.netloc.rpartition(':')[2]} is not a number in 1..{PORT_MAX}"
        raise InputError(f"'{url}': {what}")
    return str(url)


class BrokerParams(_Model):
    """Broker address and credentials (the password itself is never stored here)."""

    url: str

    @field_validator("url")
    @classmethod
    def _url(cls, v: str) -> str:
        return check_broker_url(v)
    username: str = ""
    password_file: str = ""
    password_env: str = ""
    ca_file: str = ""
    cert_file: str = ""
    key_file: str = ""
    tls_insecure: bool = False
    keepalive_s: int = Field(default=10, ge=1)
    qos: int = Field(default=1, ge=0, le=2)
    reconnect_max_s: float = Field(default=2.0, ge=MIN_DURATION_S)

    @model_validator(mode="after")
    def _login(self) -> BrokerParams:
        """A login needs its password's source, and a password source its login."""
        if self.username and not (self.password_file or self.password_env):
            raise ValueError(f"username '{self.username}' without password_file or password_env: the broker would "
                             "refuse the login (or, without authentication, it means nothing)")
        if (self.password_file or self.password_env) and not self.username:
            raise ValueError("password_file or password_env without a username")
        if self.password_file and self.password_env:
            raise ValueError("password_file and password_env both given: name one source of the password")
        return self

    @property
    def host(self) -> str:
        """Host name of :attr:`url`."""
        return urlsplit(self.url).hostname or ""

    @property
    def port(self) -> int:
        """Port of :attr:`url` (default 1883, 8883 for mqtts)."""
        return urlsplit(self.url).port or (8883 if self.tls else 1883)

    @property
    def tls(self) -> bool:
        """True for ``mqtts://``."""
        return self.url.startswith("mqtts://")


class DeviceInfo(_Model):
    """Home Assistant device block of the discovery payloads."""

    name: str
    manufacturer: str = ""
    model: str = ""
    configuration_url: str = ""  # Home Assistant's "Visit" link of the device: http(s)://... ("" = none)

    @field_validator("configuration_url")
    @classmethod
    def _http(cls, v: str) -> str:
        if v and not v.startswith(("http://", "https://")):
            raise ValueError(f"'{v}' is not an http:// or https:// URL (Home Assistant accepts no other)")
        return v


class TopicMap(_Model):
    """The whole ``mqtt`` section of ``config/mqtt.yaml``."""

    broker: BrokerParams
    base_topic: str = Field(min_length=1)
    node_id: str = Field(pattern=r"^[A-Za-z0-9_-]+$")
    discovery_prefix: str = "homeassistant"
    discovery: bool = True
    device: DeviceInfo
    max_age_s: float = Field(ge=MIN_DURATION_S)
    min_interval_s: float = Field(default=0.0, ge=0)
    measurements: dict[str, MeasurementSpec]
    setpoints: dict[str, SetpointSpec]
    sim_record_topic: str = ""

    @field_validator("base_topic", "discovery_prefix")
    @classmethod
    def _plain(cls, v: str) -> str:
        return plain_topic(v)

    @field_validator("sim_record_topic")
    @classmethod
    def _plain_or_none(cls, v: str) -> str:
        return plain_topic(v) if v else v

    @model_validator(mode="after")
    def _check(self) -> TopicMap:
        unknown = set(self.measurements) - set(MEASUREMENTS)
        if unknown:
            raise ValueError(f"unknown measurement(s) {sorted(unknown)}; known: {sorted(MEASUREMENTS)}")
        missing = [m for m in REQUIRED_MEASUREMENTS if m not in self.measurements]
        if missing:
            raise ValueError(f"measurement(s) {missing} missing (required: {list(REQUIRED_MEASUREMENTS)})")
        for m in REQUIRED_MEASUREMENTS:
            if not self.measurements[m].required:
                raise ValueError(f"measurement '{m}' cannot be optional")
        if set(self.setpoints) != set(SETPOINTS):
            raise ValueError(f"setpoints must be exactly {list(SETPOINTS)}, got {sorted(self.setpoints)}")
        modes = self.setpoints["hp_mode"].values
        if modes:
            check_mode_words(modes)
        for name, (lo, hi) in SETPOINT_DOMAINS.items():
            lim = self.setpoints[name].limits
            if lim and not (lo <= lim[0] and lim[1] <= hi):
                raise ValueError(f"setpoints.{name}.limits {list(lim)} outside the set-point's domain [{lo:g}, "
                                 f"{hi:g}]")
        topics = [s.topic for s in (*self.measurements.values(), *self.setpoints.values())]
        dup = sorted({t for t in topics if topics.count(t) > 1})
        if dup:
            raise ValueError(f"topic(s) used twice: {dup}")
        return self

    def max_age(self, name: str) -> float:
        """Staleness limit of measurement ``name`` [s]."""
        spec = self.measurements[name]
        return spec.max_age_s if spec.max_age_s is not None else self.max_age_s

    def device_limits(self, params: PlantParams) -> dict[str, tuple[float, float]]:
        """Device limits of hp_mod [-], p_fc_w [W], p_bess_w [W]: the map's, else the plant's."""
        plant = {
            "hp_mod": (0.0, 1.0),
            "p_fc_w": (0.0, params.fuel_cell.p_max_w),
            "p_bess_w": (-params.battery.p_d_max_w, params.battery.p_ch_max_w),
        }
        out = {}
        for name, default in plant.items():
            lim = self.setpoints[name].limits
            out[name] = (float(lim[0]), float(lim[1])) if lim else default
        return out

    def topic(self, *parts: str) -> str:
        """``<base_topic>/<parts...>``: the EMS's own topics."""
        return "/".join((self.base_topic, *parts))

    # -- the EMS's own topics ----------------------------------------------------
    @property
    def availability_topic(self) -> str:
        """``online`` / ``offline`` (retained; ``offline`` is the last will)."""
        return self.topic("availability")

    @property
    def state_topic(self) -> str:
        """JSON with the EMS sensors (KPIs, mode, next set-points, alarm), once per step."""
        return self.topic("state")

    @property
    def alarm_topic(self) -> str:
        """JSON alarm events (stale or out-of-range measurement, fallback)."""
        return self.topic("alarm")

    def switch_topics(self, name: str) -> tuple[str, str]:
        """``(command_topic, state_topic)`` of the switch ``name`` (``ems``, ``fallback``)."""
        return self.topic("switch", name, "set"), self.topic("switch", name, "state")

    def setting_topics(self, name: str) -> tuple[str, str]:
        """``(command_topic, state_topic)`` of the setting ``name`` (``battery_power_limit``)."""
        return self.topic("setting", name, "set"), self.topic("setting", name, "state")

    @property
    def run_topic(self) -> str:
        """Retained JSON of the running clock (start time, period), for a wall-clock building."""
        return self.topic("run")

    @property
    def step_topic(self) -> str:
        """The step the bridge announced last (the simulated house's acknowledgement)."""
        return self.topic("step")


#: Domains of the set-points' device limits (SI side): a modulation is a fraction, a FC delivers power.
SETPOINT_DOMAINS = {"hp_mod": (0.0, 1.0), "p_fc_w": (0.0, math.inf)}
#: Payload words that say "off": only heat-pump mode 0 (off) may be sent as one.
OFF_WORDS = FALSE_WORDS | {"0", "none", "stop", "standby", "idle"}


def check_mode_words(modes: dict[str, str]) -> None:
    """``setpoints.hp_mode.values`` map the modes one to one and say what they mean.

    Each of ``'0'`` (off), ``'1'`` (space heating) and ``'2'`` (hot water) maps to its own word
    (case and blanks ignored), and only mode 0 to a word of :data:`OFF_WORDS`: a map sending
    "off" for space heating would switch the heat pump off whenever the EMS heats.

    Raises
    ------
    ValueError
        Naming the modes and words that break the rule.
    """
    if set(modes) != {str(HP_OFF), str(HP_SH), str(HP_DHW)}:
        raise InputError(f"setpoints.hp_mode.values must map '0', '1' and '2', got {sorted(modes)}")
    words = {k: str(v).strip().lower() for k, v in modes.items()}
    seen: dict[str, str] = {}
    for mode, word in sorted(words.items()):
        if not word:
            raise InputError(f"setpoints.hp_mode.values: mode {mode} maps to an empty word")
        if word in seen:
            raise InputError(f"setpoints.hp_mode.values: modes {seen[word]} and {mode} both map to '{modes[mode]}' "
                             "(the device could not tell them apart)")
        seen[word] = mode
    for mode, word in words.items():
        if (word in OFF_WORDS) != (mode == str(HP_OFF)):
            what = "a word that means off" if word in OFF_WORDS else "a word that does not mean off"
            raise InputError(f"setpoints.hp_mode.values: mode {mode} "
                             f"({ {str(HP_OFF): 'off', str(HP_SH): 'space heating', str(HP_DHW): 'hot water'}[mode]}) "
                             f"maps to '{modes[mode]}', {what}")


def default_map_file() -> Path:
    """``config/mqtt.yaml``."""
    return config_dir() / "mqtt.yaml"


def load_topic_map(path: str | Path | None = None, broker_url: str | None = None, username: str | None = None,
                   password_file: str | None = None) -> TopicMap:
    """Read and check the ``mqtt`` section of ``config/mqtt.yaml`` (or ``path``).

    ``broker_url`` replaces ``broker.url``; ``username`` and ``password_file`` replace the
    broker login (the launcher's embedded broker and its per-run login).

    Raises
    ------
    ConfigError
        Naming the file and the parameter that is invalid.
    """
    path = Path(path) if path else default_map_file()
    data = read_ros_params(path).get("mqtt")
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: no 'mqtt' section")
    data = dict(data)
    if broker_url:
        data["broker"] = dict(data.get("broker", {}), url=broker_url)
    if username:
        data["broker"] = dict(data.get("broker", {}), username=username, password_file=password_file or "",
                              password_env="")
    topic_map = parse_model(TopicMap, data, str(path))
    if not username:  # the map's own login: its password's source is there now (the launcher's is written later)
        check_password_source(topic_map.broker, str(path))
    return topic_map


def check_password_source(broker: BrokerParams, where: str) -> None:
    """The topic map's ``password_file`` is a readable file, its ``password_env`` a set variable.

    Raises
    ------
    ConfigError
        Naming the map, the parameter and the file or variable.
    """
    import os

    from comems4build_ros.core.config import path_kind

    if broker.password_file:
        kind = path_kind(broker.password_file)
        if kind:
            raise ConfigError(f"{where}: parameter 'broker.password_file': {broker.password_file}: {kind}")
    if broker.password_env and broker.password_env not in os.environ:
        raise ConfigError(f"{where}: parameter 'broker.password_env': the environment variable "
                          f"{broker.password_env} is not set")


