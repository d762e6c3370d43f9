"""Live inputs for a real house: aWATTar day-ahead prices and an HTTP JSON weather forecast.

Used by the feed only when asked (``inputs:=live``); the scenario stays the default
source. Settings: ``config/live_inputs.yaml``.

* :class:`PriceSource` fetches the aWATTar market data (EPEX SPOT day-ahead, EUR/MWh)
  for today and tomorrow on start and then once a day after the publication time, with
  ``retries`` attempts per fetch, a ``timeout_s`` per attempt and, after a failed fetch,
  another try ``retry_later_s`` later. Every valid answer is merged into the known prices
  and written to a cache file (atomically), which is read back on the next start.
* :class:`WeatherSource` fetches an hourly forecast (ambient temperature, global
  horizontal irradiance) from any HTTP JSON source whose keys are configured.

A missing, late (timeout) or malformed answer never replaces valid data: the last valid
values stay in use and a warning goes to the ``warn`` callback (the feed publishes it on
``feed/events``). Hours without a live price take the price of the same hour on the
latest day that has one (the last valid day-ahead profile). A run does not start without
a live price (fetched now, or cached) for its first hour (:meth:`PriceSource.require`):
``comems4build launch --inputs live`` checks it before any node starts (exit code 2
naming the source URL), and so does the feed node itself.

:func:`live_scenario` lays a run's scenario on the wall-clock hours from now and puts the
live values in, so the feed's :class:`~comems4build_ros.core.loop.ObservationBuilder` works
on it unchanged.
"""

from __future__ import annotations

import json
import math
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from pydantic import Field, field_validator, model_validator

from comems4build_ros.core.config import (
    ConfigError,
    PlantParams,
    Section,
    load_section,
)
from comems4build_ros.core.scenario import scenario_from_frame
from comems4build_ros.core.scenario.base import CSV_COLUMNS, Scenario
from comems4build_ros.core.scenario.csvio import ScenarioError
from comems4build_ros.core.scenario.loaders import MS_PER_HOUR, parse_awattar
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import InputFileError, load_json_file, load_json_text

SECONDS_PER_DAY = 86400.0
USER_AGENT = "comems4build_ros"


class FetchError(RuntimeError):
    """Every attempt of a fetch failed (the message lists each attempt's reason)."""


class LiveInputsError(ConfigError):
    """A run on live inputs cannot start: no live price for its first hour (names the source URL)."""


class _Model(Section):
    """A live-input section: the parameter rule of :class:`~comems4build_ros.core.config.Section`."""


#: Most attempts of one fetch: a source that failed ten times in a row is down; more attempts only
#: delay the step (the feed tries again ``retry_later_s`` later, and stands in meanwhile).
MAX_RETRIES = 10
#: Longest time one fetch may take over all its attempts [s]: an hourly step (the feed waits for it).
MAX_FETCH_S = 3600.0


def check_url(url: str) -> str:
    """``url`` if it is ``http(s)://host[:port]/...`` without credentials or blanks.

    Credentials in the URL (``user:password@``) would stand in the parameter file, the run
    plan and every node's parameters, which any local user can list; a source that needs a
    login is not supported.

    Raises
    ------
    InputError
        Saying what is wrong.
    """
    parts = urllib.parse.urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.hostname or any(c.isspace() for c in url):
        raise InputError(f"'{url}' is not an http:// or https:// URL with a host")
    if "@" in parts.netloc:
        raise InputError(f"'{parts.scheme}://...@{parts.hostname}': no credentials in the URL (they would be "
                         "readable in the parameter file and by every local user in the nodes' parameters)")
    try:
        parts.port  # noqa: B018 (the check: a port that is no number in 0..65535 raises)
    except ValueError:
        raise InputError(f"'{url}': the port is not a number in 0..65535") from None
    return url


class _FetchParams(_Model):
    """Fetch settings both live sources share."""

    timeout_s: float = Field(ge=0.1, le=600)  # per attempt [s]: a network round trip takes at least milliseconds
    retries: int = Field(ge=1, le=MAX_RETRIES)  # attempts per fetch
    retry_delay_s: float = Field(ge=0, le=MAX_FETCH_S)  # wait between attempts [s]
    cache_file: str = ""

    @model_validator(mode="after")
    def _bounded(self) -> _FetchParams:
        worst = self.retries * self.timeout_s + (self.retries - 1) * self.retry_delay_s
        if worst > MAX_FETCH_S:
            raise ValueError(f"retries x timeout_s + (retries - 1) x retry_delay_s = {worst:g} s: one fetch could "
                             f"block the feed longer than an hourly step ({MAX_FETCH_S:g} s)")
        return self


class LivePriceParams(_FetchParams):
    """``live_inputs.prices`` of ``config/live_inputs.yaml``.

    Attributes
    ----------
    timeout_s : float
        Time limit of one attempt [s].
    retries : int
        Attempts per fetch.
    retry_delay_s : float
        Wait between attempts [s].
    cache_file : str
        Cache file (empty: the default location).
    url : str
        aWATTar market-data endpoint (http or https).
    publication_time : str
        Local ``HH:MM`` after which the next day's day-ahead prices are fetched.
    days_ahead : int
        Days requested, today included.
    retry_later_s : float
        Wait after a failed fetch before the next one [s].
    """

    url: str = Field(pattern=r"^https?://")
    publication_time: str = Field(pattern=r"^([01]\d|2[0-3]):[0-5]\d$")
    days_ahead: int = Field(ge=1, le=7)
    retry_later_s: float = Field(ge=10)  # [s]: sooner than 10 s a source that just failed has not changed

    @field_validator("url")
    @classmethod
    def _url(cls, v: str) -> str:
        return check_url(v)


class LiveWeatherParams(_FetchParams):
    """``live_inputs.weather`` of ``config/live_inputs.yaml``.

    Attributes
    ----------
    timeout_s, retries, retry_delay_s, cache_file
        As for :class:`LivePriceParams`.
    url : str
        HTTP JSON forecast endpoint (empty: no live weather).
    time_key, t_amb_key, ghi_key : str
        Dotted keys of the time list, the ambient temperatures [degC] and the global
        horizontal irradiances [W/m2] in the answer.
    time_format : str
        ``iso``, ``unix_s`` or ``unix_ms``.
    refresh_s : float
        Time between fetches [s].
    """

    url: str = ""
    time_key: str
    time_format: str = Field(pattern="^(iso|unix_s|unix_ms)$")
    t_amb_key: str
    ghi_key: str
    refresh_s: float = Field(ge=60)  # [s]: forecasts come as hourly values, refreshed hourly at the source

    @field_validator("url")
    @classmethod
    def _url(cls, v: str) -> str:
        return check_url(v) if v else v


class LiveInputParams(_Model):
    """The ``live_inputs`` section.

    Attributes
    ----------
    prices : LivePriceParams
    weather : LiveWeatherParams
    """

    prices: LivePriceParams
    weather: LiveWeatherParams


def load_live_settings(path: str | Path | None = None) -> LiveInputParams:
    """Read the live-input settings.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        Parameter file with a ``live_inputs`` section; default ``config/live_inputs.yaml``.

    Returns
    -------
    LiveInputParams
        The validated settings.

    Raises
    ------
    ConfigError
        Naming the file and the parameter.
    """
    return load_section(LiveInputParams, path, "live_inputs.yaml", "live_inputs")


def http_get(url: str, timeout_s: float, retries: int, retry_delay_s: float,
             sleep: Callable[[float], None] = time.sleep) -> str:
    """GET ``url`` with up to ``retries`` attempts.

    Parameters
    ----------
    url : str
        The URL.
    timeout_s : float
        Time limit of one attempt [s].
    retries : int
        Attempts.
    retry_delay_s : float
        Wait between attempts [s].
    sleep : callable, optional
        The wait (tests pass their own).

    Returns
    -------
    str
        The body, decoded as UTF-8.

    Raises
    ------
    FetchError
        After the last failed attempt, naming the URL and every attempt's reason (HTTP
        status, timeout, connection refused, ...).
    """
    errors = []
    for attempt in range(1, retries + 1):
        try:
            request = urllib.request.Request(url, headers={"User-Agent": USER_AGENT})
            with urllib.request.urlopen(request, timeout=timeout_s) as response:  # noqa: S310 (configured URL)
                return response.read().decode("utf-8")
        except urllib.error.HTTPError as exc:
            errors.append(f"attempt {attempt}: HTTP {exc.code} {exc.reason}")
        except (TimeoutError, urllib.error.URLError, OSError, UnicodeDecodeError) as exc:
            reason = getattr(exc, "reason", exc)
            errors.append(f"attempt {attempt}: {'timeout' if isinstance(reason, TimeoutError) else reason}")
        if attempt < retries:
            sleep(retry_delay_s)
    raise FetchError(f"{url}: {retries} attempt(s) failed: " + "; ".join(errors))


def write_json_atomic(path: Path, doc: Any) -> None:
    """Write a document as JSON through a temporary file in the same directory and a rename.

    The file gets mode 0600 (a later run reads the cache again) and is never written through
    a link (:func:`comems4build_ros.files.outputs.write_text_atomic`).

    Parameters
    ----------
    path : pathlib.Path
        The file; its directory is created.
    doc : object
        JSON-serialisable document.
    """
    from comems4build_ros.files.outputs import write_text_atomic

    write_text_atomic(path, json.dumps(doc), private=True)


def _series_to_doc(series: pd.Series) -> dict[str, float]:
    """Return a UTC-indexed series as ``{unix seconds: value}`` for the cache file."""
    return {str(int(t.timestamp())): float(v) for t, v in series.items()}


def _series_from_doc(doc: Any, name: str) -> pd.Series:
    """Return the series of a cache document (:func:`_series_to_doc`), sorted."""
    index = pd.to_datetime([int(k) for k in doc], unit="s", utc=True)
    return pd.Series([float(v) for v in doc.values()], index=index, name=name).sort_index()


class _CachedSource:
    """What both sources share: settings, time zone, cache file, warning callback, clock."""

    def __init__(self, settings: Any, timezone: str, cache_path: Path, warn: Callable[[str], None],
                 now: Callable[[], float] = time.time, sleep: Callable[[float], None] = time.sleep) -> None:
        self.settings = settings
        self.tz = timezone
        self.cache_path = Path(cache_path)
        self.warn = warn
        self.now = now
        self.sleep = sleep
        self.last_attempt: float | None = None
        self.warnings = 0
        self.last_warning = ""

    def _warn(self, text: str) -> None:
        """Count and remember a warning, and pass it on."""
        self.warnings += 1
        self.last_warning = text
        self.warn(text)


class PriceSource(_CachedSource):
    """aWATTar day-ahead prices with retries, a daily schedule and a cache (module docstring).

    Parameters
    ----------
    settings : LivePriceParams
        Price settings.
    timezone : str
        The site's IANA time zone (publication time and "today").
    cache_path : pathlib.Path
        Cache file (JSON: UTC hour start [s] -> price [EUR/MWh]); read on start if present.
    warn : callable
        Receives one line per failed fetch.
    now : callable, optional
        Clock [s since the epoch] (tests pass their own).
    sleep : callable, optional
        Wait between attempts [s] (tests pass their own).
    """

    def __init__(self, settings: LivePriceParams, timezone: str, cache_path: Path, warn: Callable[[str], None],
                 now: Callable[[], float] = time.time, sleep: Callable[[float], None] = time.sleep) -> None:
        super().__init__(settings, timezone, cache_path, warn, now, sleep)
        self.prices = pd.Series(dtype=float, name="spot_eur_per_mwh")
        self.last_success: float | None = None
        if self.cache_path.is_file():
            try:
                doc = load_json_file(self.cache_path, "the price cache")
                self.prices = _series_from_doc(doc["prices"], "spot_eur_per_mwh")
            except (OSError, ValueError, KeyError, TypeError) as exc:
                self._warn(f"cache {self.cache_path} unreadable ({exc}); starting without cached prices")

    def _local_midnight(self, t: float) -> pd.Timestamp:
        """Return the local midnight of the day of ``t`` [s since the epoch]."""
        return pd.Timestamp(t, unit="s", tz="UTC").tz_convert(self.tz).normalize()

    def next_due(self) -> float:
        """Return when the next fetch is due.

        Returns
        -------
        float
            Time [s since the epoch]: -inf if never fetched, else the next publication time
            after the last success, or ``retry_later_s`` after a failure.
        """
        if self.last_attempt is None:
            return -math.inf
        if self.last_success is None or self.last_success < self.last_attempt:
            return self.last_attempt + self.settings.retry_later_s
        hh, mm = (int(x) for x in self.settings.publication_time.split(":"))
        day = self._local_midnight(self.last_success)
        publication = day + pd.Timedelta(hours=hh, minutes=mm)
        if publication.timestamp() <= self.last_success:
            publication += pd.Timedelta(days=1)
        return publication.timestamp()

    def url_for(self, t: float) -> str:
        """Return the request URL for today (local) and the ``days_ahead - 1`` following days.

        Parameters
        ----------
        t : float
            Now [s since the epoch].

        Returns
        -------
        str
            The URL with ``start`` and ``end`` in epoch milliseconds (aWATTar API).
        """
        start = self._local_midnight(t)
        end = start + pd.Timedelta(days=self.settings.days_ahead)
        query = urllib.parse.urlencode({"start": int(start.timestamp() * 1000), "end": int(end.timestamp() * 1000)})
        return f"{self.settings.url}?{query}"

    def refresh(self, force: bool = False) -> bool:
        """Fetch the prices if due; failures only warn.

        Parameters
        ----------
        force : bool, optional
            Fetch now, whatever :meth:`next_due` says.

        Returns
        -------
        bool
            True if new prices were merged (and the cache written).
        """
        t = self.now()
        if not force and t < self.next_due():
            return False
        self.last_attempt = t
        url = self.url_for(t)
        s = self.settings
        try:
            text = http_get(url, s.timeout_s, s.retries, s.retry_delay_s, self.sleep)
            series = parse_awattar(text, url)
        except (FetchError, ScenarioError) as exc:
            self._warn(f"day-ahead prices: {exc}; using the last valid prices ({self.describe()})")
            return False
        today = self._local_midnight(t).tz_convert("UTC")
        if series.index.max() < today:
            self._warn(f"day-ahead prices: {url}: no price for today or later; using the last valid prices "
                       f"({self.describe()})")
            return False
        self.prices = series.combine_first(self.prices).sort_index()
        self.last_success = t
        write_json_atomic(self.cache_path, {"source": s.url, "fetched_unix_s": t,
                                            "prices": _series_to_doc(self.prices)})
        return True

    def has_price(self, t: float) -> bool:
        """Tell whether a live price (fetched now or cached) is known for the hour of ``t`` itself.

        No other day's price stands in for it here.

        Parameters
        ----------
        t : float
            Any time within the hour [s since the epoch].

        Returns
        -------
        bool
            True if the hour has a live price.
        """
        hour = pd.Timestamp(t, unit="s", tz="UTC").floor("h")
        return hour in self.prices.index and not math.isnan(float(self.prices[hour]))

    def known(self, times: pd.DatetimeIndex) -> np.ndarray:
        """Tell for each hour start whether a live price is known for that hour itself.

        Parameters
        ----------
        times : pandas.DatetimeIndex
            Hour starts, tz-aware.

        Returns
        -------
        numpy.ndarray of bool
            False where :meth:`values` gives another day's price standing in for it.
        """
        if self.prices.empty:
            return np.zeros(len(times), dtype=bool)
        known = self.prices.reindex(pd.DatetimeIndex(times).tz_convert("UTC"))
        return ~np.isnan(known.to_numpy(dtype=float))

    def require(self, t: float) -> None:
        """Refuse a run on live inputs without a live price for the hour of ``t`` (its first step).

        Parameters
        ----------
        t : float
            Start of the run [s since the epoch].

        Raises
        ------
        LiveInputsError
            Naming the source URL and why (the last failed fetch, or what is known).
        """
        if self.has_price(t):
            return
        hour = pd.Timestamp(t, unit="s", tz="UTC").floor("h").tz_convert(self.tz)
        why = self.last_warning or f"no price for that hour in the answer ({self.describe()})"
        raise LiveInputsError(
            f"live inputs: no day-ahead price for the run's first hour {hour.isoformat()} from {self.settings.url} "
            f"({why}). A run on live inputs does not start on stand-in prices (the scenario's laid on today's "
            "hours); check the network and the source, or run on the scenario's inputs (--inputs scenario)")

    def describe(self) -> str:
        """Describe which prices are known (for warnings).

        Returns
        -------
        str
            ``none known yet`` or how many hours are known and up to when.
        """
        if self.prices.empty:
            return "none known yet"
        return f"{len(self.prices)} h known up to {self.prices.index.max().isoformat()}"

    def values(self, times: pd.DatetimeIndex) -> np.ndarray:
        """Return the spot price for each hour start.

        Hours without a live price take the same local hour of the latest day that has one.

        Parameters
        ----------
        times : pandas.DatetimeIndex
            The run's hour starts, tz-aware in any zone.

        Returns
        -------
        numpy.ndarray
            Spot price [EUR/MWh]; NaN everywhere if none is known.
        """
        out = np.full(len(times), np.nan)
        if self.prices.empty:
            return out
        utc = pd.DatetimeIndex(times).tz_convert("UTC")
        known = self.prices.reindex(utc)
        out[:] = known.to_numpy(dtype=float)
        missing = np.flatnonzero(np.isnan(out))
        if missing.size:
            local = self.prices.copy()
            local.index = local.index.tz_convert(self.tz)
            by_hour = local.groupby(local.index.hour).last()  # latest day's value per local hour
            hours = pd.DatetimeIndex(times).tz_convert(self.tz).hour[missing]
            out[missing] = by_hour.reindex(hours).to_numpy(dtype=float)
        return out


def _dig(doc: Any, dotted: str, source: str) -> Any:
    """Return the value under a dotted key of a JSON document, or raise ScenarioError naming it."""
    cur = doc
    for part in dotted.split("."):
        if not isinstance(cur, dict) or part not in cur:
            raise ScenarioError(f"{source}: key '{dotted}' missing")
        cur = cur[part]
    return cur


def parse_weather(text: str, settings: LiveWeatherParams, timezone: str, source: str) -> pd.DataFrame:
    """Parse a weather-forecast answer into hourly means.

    Parameters
    ----------
    text : str
        The JSON answer.
    settings : LiveWeatherParams
        Its keys and time format.
    timezone : str
        Zone of naive ISO times.
    source : str
        The URL, for messages.

    Returns
    -------
    pandas.DataFrame
        ``t_amb_c`` [degC] and ``ghi_w_m2`` [W/m2], hourly means on a UTC index.

    Raises
    ------
    ScenarioError
        Naming the source and the key for bad JSON, a missing key, lists of different
        lengths, a time that cannot be read or a value that is not a finite number.
    """
    try:
        doc = load_json_text(text, str(source))
    except InputFileError as exc:
        raise ScenarioError(str(exc)) from None
    times = _dig(doc, settings.time_key, source)
    cols = {"t_amb_c": _dig(doc, settings.t_amb_key, source), "ghi_w_m2": _dig(doc, settings.ghi_key, source)}
    if not isinstance(times, list) or not times:
        raise ScenarioError(f"{source}: key '{settings.time_key}' is not a non-empty list")
    for name, values in cols.items():
        key = settings.t_amb_key if name == "t_amb_c" else settings.ghi_key
        if not isinstance(values, list) or len(values) != len(times):
            raise ScenarioError(f"{source}: key '{key}' is not a list of {len(times)} values")
        for i, v in enumerate(values):
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ScenarioError(f"{source}: key '{key}'[{i}]: {v!r} is not a number")
    try:
        if settings.time_format == "iso":
            idx = pd.DatetimeIndex(pd.to_datetime(times))
            idx = idx.tz_localize(timezone) if idx.tz is None else idx
        else:
            unit = "s" if settings.time_format == "unix_s" else "ms"
            idx = pd.DatetimeIndex(pd.to_datetime(times, unit=unit, utc=True))
    except (ValueError, TypeError) as exc:
        raise ScenarioError(f"{source}: key '{settings.time_key}': unreadable time ({exc})") from None
    frame = pd.DataFrame(cols, index=idx.tz_convert("UTC"), dtype=float)
    return frame.resample("1h").mean().dropna()


class WeatherSource(_CachedSource):
    """HTTP JSON weather forecast with retries, periodic refresh and a cache (module docstring).

    Parameters
    ----------
    settings : LiveWeatherParams
        Weather settings.
    timezone : str
        The site's IANA time zone.
    cache_path : pathlib.Path
        Cache file (JSON: per series, UTC hour start [s] -> value); read on start if present.
    warn, now, sleep : callable
        As for :class:`PriceSource`.
    """

    def __init__(self, settings: LiveWeatherParams, timezone: str, cache_path: Path, warn: Callable[[str], None],
                 now: Callable[[], float] = time.time, sleep: Callable[[float], None] = time.sleep) -> None:
        super().__init__(settings, timezone, cache_path, warn, now, sleep)
        self.frame = pd.DataFrame(columns=["t_amb_c", "ghi_w_m2"], dtype=float)
        if self.cache_path.is_file():
            try:
                doc = load_json_file(self.cache_path, "the weather cache")
                self.frame = pd.DataFrame({k: _series_from_doc(doc[k], k) for k in ("t_amb_c", "ghi_w_m2")})
            except (OSError, ValueError, KeyError, TypeError) as exc:
                self._warn(f"weather cache {self.cache_path} unreadable ({exc}); starting without it")

    @property
    def enabled(self) -> bool:
        """False when no URL is configured."""
        return bool(self.settings.url)

    def refresh(self, force: bool = False) -> bool:
        """Fetch the forecast if ``refresh_s`` passed since the last attempt; failures only warn.

        Parameters
        ----------
        force : bool, optional
            Fetch now, even before ``refresh_s`` has passed.

        Returns
        -------
        bool
            True if new values were merged (and the cache written); False also without a URL.
        """
        t = self.now()
        if not self.enabled or (not force and self.last_attempt is not None
                                and t - self.last_attempt < self.settings.refresh_s):
            return False
        self.last_attempt = t
        s = self.settings
        try:
            frame = parse_weather(http_get(s.url, s.timeout_s, s.retries, s.retry_delay_s, self.sleep), s, self.tz,
                                  s.url)
        except (FetchError, ScenarioError) as exc:
            self._warn(f"weather forecast: {exc}; using the last valid forecast "
                      f"({len(self.frame)} h known)")
            return False
        self.frame = frame.combine_first(self.frame).sort_index()
        write_json_atomic(self.cache_path, {k: _series_to_doc(self.frame[k]) for k in ("t_amb_c", "ghi_w_m2")})
        return True

    def values(self, times: pd.DatetimeIndex, name: str) -> np.ndarray:
        """Return the forecast of one series for each hour start.

        Parameters
        ----------
        times : pandas.DatetimeIndex
            Hour starts, tz-aware.
        name : str
            ``t_amb_c`` [degC] or ``ghi_w_m2`` [W/m2].

        Returns
        -------
        numpy.ndarray
            Values in the series' unit; NaN where the forecast has none.
        """
        if self.frame.empty:
            return np.full(len(times), np.nan)
        return self.frame[name].reindex(pd.DatetimeIndex(times).tz_convert("UTC")).to_numpy(dtype=float)


#: Kind of the ``feed/events`` line that states, from its step on, which live inputs stand-in
#: values replace (:func:`stand_in_state`): ``<step> stand_in <state>: <explanation>``.
STAND_IN_EVENT = "stand_in"
#: States of :data:`STAND_IN_EVENT` lines: nothing replaced, or the inputs replaced.
STAND_IN_STATES = ("none", "prices", "weather", "prices+weather")


def stand_in_state(times: pd.DatetimeIndex, prices: PriceSource,
                   weather: WeatherSource | None = None) -> list[str]:
    """Tell for each hour start which live inputs :func:`live_scenario` had to replace by stand-in values.

    Prices stand in for an hour without a live price (the same hour of the latest day with
    prices); weather where the forecast has no value or no weather source is configured
    (the scenario's).

    Parameters
    ----------
    times : pandas.DatetimeIndex
        Hour starts, tz-aware.
    prices : PriceSource
        The price source.
    weather : WeatherSource, optional
        The weather source.

    Returns
    -------
    list of str
        One of :data:`STAND_IN_STATES` per hour.
    """
    price = ~prices.known(times)
    wx = np.ones(len(times), dtype=bool)
    if weather is not None and weather.enabled:
        wx = np.isnan(weather.values(times, "t_amb_c")) | np.isnan(weather.values(times, "ghi_w_m2"))
    return [STAND_IN_STATES[int(p) + 2 * int(w)] for p, w in zip(price, wx)]


def live_scenario(base: Scenario, params: PlantParams, start: pd.Timestamp, prices: PriceSource,
                  weather: WeatherSource | None = None) -> Scenario:
    """Lay a scenario on the hours from ``start`` and put the live prices and weather in it.

    The load and hot-water series of ``base`` are kept step by step; the comfort bounds
    are recomputed for the new hours (``eq:T_min``); the spot price comes from ``prices``
    (the scenario's where no live price is known at all) and the buy price from the plant's
    tariff (``eq:costs``); ambient temperature and global irradiance come from ``weather``
    where it has values, with the diffuse part limited to the global value.

    Parameters
    ----------
    base : Scenario
        The scenario whose series are laid on the new hours.
    params : PlantParams
        Plant parameters (time zone, tariff, comfort).
    start : pandas.Timestamp
        First hour of the run (floored to the hour), tz-aware.
    prices : PriceSource
        Live day-ahead prices.
    weather : WeatherSource, optional
        Live weather forecast.

    Returns
    -------
    Scenario
        Named ``<base>+live``, ``n_steps`` as in ``base``.
    """
    start = pd.Timestamp(start).tz_convert(params.site.timezone).floor("h")
    time_index = pd.date_range(start, periods=len(base.time), freq=pd.Timedelta(milliseconds=MS_PER_HOUR))
    frame = pd.DataFrame({c: getattr(base, c) for c in CSV_COLUMNS if c != "time" and hasattr(base, c)},
                         index=time_index)
    spot = prices.values(time_index)
    frame["spot_eur_per_mwh"] = np.where(np.isnan(spot), frame["spot_eur_per_mwh"], spot)
    frame = frame.drop(columns=["price_buy_eur_per_kwh"], errors="ignore")  # tariff from the live spot price
    if weather is not None and weather.enabled:
        for name in ("t_amb_c", "ghi_w_m2"):
            v = weather.values(time_index, name)
            frame[name] = np.where(np.isnan(v), frame[name], v)
        frame["dhi_w_m2"] = np.minimum(frame["dhi_w_m2"], frame["ghi_w_m2"])
    meta = dict(base.meta, live_inputs={"start": start.isoformat(), "prices": prices.describe()})
    return scenario_from_frame(f"{base.name}+live", frame, params, base.n_steps, meta)
