"""A detailed building model in co-simulation: EnergyPlus through its runtime API.

EnergyPlus (``pyenergyplus``, the API of the ``pyenergyplus-lbnl`` wheel, EnergyPlus 25.2)
runs the house of an IDF file in this process, in a thread of its own; the plant drives it
one step (one hour) at a time:

1. :meth:`EnergyPlusBuilding.initial_temperatures` writes the run's weather as an EPW
   (:mod:`~comems4build_ros.core.models.epw`), adds ``RunPeriod`` and ``Site:Location`` to
   the IDF and starts EnergyPlus. Its warm-up days (the first day repeated until the
   temperatures converge) and any hours of the first day before the run's first step are
   heated by a proportional-integral thermostat that holds the air at T_air,init, as the
   4R3C's walls start as if the house had been held there.
2. Each :meth:`EnergyPlusBuilding.step` hands the step's floor heat and appliance load to
   the EnergyPlus thread and waits. At the start of the hour's first zone time step (callback
   ``begin_zone_timestep_after_init_heat_balance``) the thread takes the step's values; at the
   start of every system time step (``begin_system_timestep_before_predictor``) it sets the
   actuators: the appliances' electricity rate (W, released as heat in the zones) and, for
   heat (>= 0), the set point of each zone's electric low-temperature radiant system, computed
   from the zone's current air temperature so that the system's ``HalfFlowPower`` control
   gives exactly its share of the plant's heat (split by the heated floors' areas), which
   EnergyPlus puts into the screed at the pipes' level; for cooling (< 0) the heat flux
   schedule of the floors' top-face source terms (W/m2). At the end of each zone time step
   (``end_zone_timestep_after_zone_reporting``) the zones' air temperatures and the heat
   EnergyPlus reports it received (``Zone Radiant HVAC Heating Rate`` and ``Surface Inside
   Face Heat Source Gain Rate per Area``) are read. After the hour's last zone time step the
   thread hands the results back and waits for the next step. An IDF without radiant systems
   takes the heat through the source terms as well.
3. :meth:`EnergyPlusBuilding.close` stops EnergyPlus (also mid-run) and joins the thread.

What the plant reads: T_air = the floor-area-weighted mean of the zones' mean air temperature
at the end of the hour; "T_w,in" = the mean inside face temperature of the heated floors and
"T_w,out" = the mean inside face temperature of the exterior walls (measured surface
temperatures, not the 4R3C's nodes; an MPC plans with its own model's states). Per step the
record :attr:`EnergyPlusBuilding.last` keeps what EnergyPlus received and reported, with the sun
the windows let in and the internal gains released in the zones (``comems4build house``
compares them with the 4R3C's).

The IDF must define what the co-simulation actuates (:func:`check_idf`): the schedule
:data:`~comems4build_ros.core.models.house_idf.HEAT_SCHEDULE`, a heat balance source
term on each heated floor, ``ElectricEquipment`` in each zone, and, for heat into the floor's
mass, ``ZoneHVAC:LowTemperatureRadiant:Electric`` systems controlled on the mean air
temperature with ``HalfFlowPower`` and a ``Schedule:Constant`` set point; the shipped house
(:mod:`~comems4build_ros.core.models.house_idf`) has them all.
"""

from __future__ import annotations

import math
import queue
import shutil
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from comems4build_ros.core.config import SiteParams
from comems4build_ros.core.models import house_idf as house
from comems4build_ros.core.models.building import Temperatures
from comems4build_ros.core.models.epw import Weather, check_epw_covers, standard_offset_h, standard_times, write_epw
from comems4build_ros.core.types import Exogenous
from comems4build_ros.files.errors import InputError
from comems4build_ros.files.inputs import ASCII_SPACE, parse_decimal, parse_integer, text_lines

#: Largest zone time step allowed [min].
MAX_ZONE_STEP_MIN = 15
#: Warm-up thermostat: proportional gain [W/K], integral gain [W/(K zone step)], largest heat [W].
WARMUP_KP_W_PER_K = 3000.0
WARMUP_KI_W_PER_K = 300.0
WARMUP_Q_MAX_W = 20000.0
#: Seconds the plant waits for EnergyPlus to finish one hour before it gives up.
STEP_TIMEOUT_S = 600.0
#: Output variable of the heat EnergyPlus puts into a surface's inside face [W/m2].
SOURCE_VARIABLE = "Surface Inside Face Heat Source Gain Rate per Area"
#: Output variable of the heat an electric radiant system puts into its construction [W].
RADIANT_VARIABLE = "Zone Radiant HVAC Heating Rate"
#: The air temperature a radiant system's control reads, as of the current system time step [degC].
CONTROL_VARIABLE = "Zone Air Temperature"
#: Set point that keeps an electric radiant system off [degC].
RADIANT_OFF_C = -100.0
#: Output variables of each zone the record keeps (hourly means, summed over the zones) [W]: the sun
#: the windows let in, and the internal gains released in the zone (people, equipment, lights).
SOLAR_VARIABLE = "Enclosure Windows Total Transmitted Solar Radiation Rate"
INTERNAL_VARIABLE = "Zone Total Internal Total Heating Rate"


class IDFError(InputError):
    """An IDF that cannot serve the co-simulation; the message names the file and the object or field."""


@dataclass
class IDFInterface:
    """What the co-simulation found in an IDF: the zones, heated floors and appliance objects.

    Attributes
    ----------
    zones : list of str
        ``Zone`` names.
    floors : list of str
        Surfaces whose ``SurfaceProperty:HeatBalanceSourceTerm`` takes the floor heat.
    appliances : list of str
        ``ElectricEquipment`` objects (the appliance load's heat).
    exterior_walls : list of str
        Walls facing outdoors.
    timesteps_per_hour : int
        EnergyPlus zone time steps per hour.
    floor_areas_m2 : list of float
        Areas of the heated floors [m2].
    people : list of str
        ``People`` objects.
    radiant : list of Radiant
        Electric radiant systems driven through their set point.
    """

    zones: list[str]
    floors: list[str]
    appliances: list[str]
    exterior_walls: list[str]
    timesteps_per_hour: int
    floor_areas_m2: list[float]
    people: list[str] = field(default_factory=list)
    radiant: list[Radiant] = field(default_factory=list)


@dataclass
class Radiant:
    """An electric low-temperature radiant system the co-simulation drives through its set point.

    Attributes
    ----------
    name : str
        The ``ZoneHVAC:LowTemperatureRadiant:Electric`` object.
    zone : str
        Its zone.
    surface : str
        The heated surface.
    setpoint : str
        Its set-point schedule (``Schedule:Constant``).
    capacity_w : float
        Heating design capacity [W].
    throttling_k : float
        Heating throttling range [K].
    area_m2 : float
        Area of the heated surface [m2] (the plant's heat is split by it).
    """

    name: str
    zone: str
    surface: str
    setpoint: str
    capacity_w: float
    throttling_k: float
    area_m2: float


def _surface_area_m2(surf: list[str]) -> float:
    """Area [m2] of a ``BuildingSurface:Detailed`` object from its vertex count and coordinates.

    Raises ``ValueError`` or ``IndexError`` for a count or coordinate that is not a plain
    number or for missing vertices; the callers name the object.
    """
    n = parse_integer(surf[11])
    coords = surf[12:12 + 3 * n]
    if n < 3 or len(coords) != 3 * n:
        raise IndexError(f"{n} vertices")
    return polygon_area_m2([parse_decimal(v) for v in coords])


def polygon_area_m2(coords: list[float]) -> float:
    """Compute the area of a planar polygon by Newell's method.

    Parameters
    ----------
    coords : list of float
        Vertex coordinates x1, y1, z1, x2, ... [m].

    Returns
    -------
    float
        Area [m2].
    """
    pts = np.asarray(coords, dtype=float).reshape(-1, 3)
    nxt = np.roll(pts, -1, axis=0)
    normal = np.cross(pts, nxt).sum(axis=0)
    return float(np.linalg.norm(normal) / 2.0)


def _objects(text: str) -> list[list[str]]:
    """Split the IDF into objects, each a list of fields (comments removed, whitespace stripped)."""
    body = "\n".join(line.split("!", 1)[0] for line in text_lines(text))
    out = []
    for chunk in body.split(";"):
        fields = [f.strip(ASCII_SPACE) for f in chunk.split(",")]
        if fields and fields[0]:
            out.append(fields)
    return out


def check_idf(path: str | Path) -> IDFInterface:
    """Read an IDF and check that it has what the co-simulation actuates and reads.

    Parameters
    ----------
    path : str or Path
        The IDF (EnergyPlus 25.x input file).

    Returns
    -------
    IDFInterface
        The objects the co-simulation uses.

    Raises
    ------
    IDFError
        Naming the file and the missing or invalid object or field: no ``Version`` 25.x, no
        zone, no ``Schedule:Constant`` named ``C4B Floor Heat Flux``, no
        ``SurfaceProperty:HeatBalanceSourceTerm`` using it, a source term on an unknown
        surface, no ``ElectricEquipment``, or a zone time step longer than 15 min.
    """
    path = Path(path)
    if not path.is_file():
        raise IDFError(f"{path}: IDF file not found")
    try:
        objs = _objects(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise IDFError(f"{path}: not a text IDF file ({exc.reason})") from None
    kinds: dict[str, list[list[str]]] = {}
    for o in objs:
        kinds.setdefault(o[0].lower(), []).append(o)
    versions = kinds.get("version", [])
    if not versions or len(versions[0]) < 2 or not versions[0][1].startswith("25."):
        got = versions[0][1] if versions and len(versions[0]) > 1 else "none"
        raise IDFError(f"{path}: object Version: field Version Identifier must be 25.x (EnergyPlus 25.2), got {got}")
    zones = [o[1] for o in kinds.get("zone", []) if len(o) > 1]
    if not zones:
        raise IDFError(f"{path}: object Zone: the IDF has no zone")
    heat = house.HEAT_SCHEDULE.lower()
    sched = [o for o in kinds.get("schedule:constant", []) if len(o) > 1 and o[1].lower() == heat]
    if not sched:
        raise IDFError(f"{path}: object Schedule:Constant: field Name: no schedule named '{house.HEAT_SCHEDULE}' "
                       "(the floor heat flux the co-simulation sets, W/m2)")
    surfaces = {o[1].lower(): o for o in kinds.get("buildingsurface:detailed", []) if len(o) > 4}
    floors: list[str] = []
    areas: list[float] = []
    for o in kinds.get("surfaceproperty:heatbalancesourceterm", []):
        if len(o) > 2 and o[2].lower() == house.HEAT_SCHEDULE.lower():
            if o[1].lower() not in surfaces:
                raise IDFError(f"{path}: object SurfaceProperty:HeatBalanceSourceTerm: field Surface Name: "
                               f"'{o[1]}' is no BuildingSurface:Detailed of the file")
            floors.append(o[1])
            surf = surfaces[o[1].lower()]
            try:
                areas.append(_surface_area_m2(surf))
            except (ValueError, IndexError):
                raise IDFError(f"{path}: object BuildingSurface:Detailed '{o[1]}': field Number of Vertices or a "
                               "vertex coordinate is not a number") from None
    if not floors:
        raise IDFError(f"{path}: object SurfaceProperty:HeatBalanceSourceTerm: field Inside Face Heat Source Term "
                       f"Schedule Name: no surface uses '{house.HEAT_SCHEDULE}' (where the heat goes)")
    appliances = [o[1] for o in kinds.get("electricequipment", []) if len(o) > 1]
    if not appliances:
        raise IDFError(f"{path}: object ElectricEquipment: none (the appliance load's heat goes there)")
    walls = [o[1] for o in kinds.get("buildingsurface:detailed", [])
             if len(o) > 6 and o[2].lower() == "wall" and o[6].lower() == "outdoors"]
    steps = kinds.get("timestep", [])
    try:
        n = parse_integer(steps[0][1]) if steps and len(steps[0]) > 1 else 6
    except ValueError:
        raise IDFError(f"{path}: object Timestep: field Number of Timesteps per Hour: {steps[0][1][:40]!r} "
                       "is not a whole number") from None
    if n <= 0:
        raise IDFError(f"{path}: object Timestep: field Number of Timesteps per Hour = {n}, must be > 0")
    if 60 / n > MAX_ZONE_STEP_MIN:
        raise IDFError(f"{path}: object Timestep: field Number of Timesteps per Hour = {n} gives "
                       f"{60 / n:g} min, at most {MAX_ZONE_STEP_MIN} min allowed (at least 4 per hour)")
    people = [o[1] for o in kinds.get("people", []) if len(o) > 1]
    constants = {o[1].lower() for o in kinds.get("schedule:constant", []) if len(o) > 1}
    radiant = [_radiant(path, o, surfaces, constants) for o in kinds.get("zonehvac:lowtemperatureradiant:electric", [])]
    return IDFInterface(zones, floors, appliances, walls, n, areas, people, radiant)


def _radiant(path: Path, o: list[str], surfaces: dict[str, list[str]], constants: set[str]) -> Radiant:
    """Read a ``ZoneHVAC:LowTemperatureRadiant:Electric`` the co-simulation can drive exactly (else IDFError)."""
    where = f"{path}: object ZoneHVAC:LowTemperatureRadiant:Electric '{o[1] if len(o) > 1 else ''}'"
    f = o + [""] * (13 - len(o))
    if f[5].lower() != "heatingdesigncapacity":
        raise IDFError(f"{where}: field Heating Design Capacity Method must be HeatingDesignCapacity")
    try:
        capacity, throttling = parse_decimal(f[6]), parse_decimal(f[11])
    except ValueError:
        raise IDFError(f"{where}: field Heating Design Capacity or Heating Throttling Range is not a number "
                       "(autosize is not driven)") from None
    if not (0 < capacity < math.inf and 0 < throttling < math.inf):
        raise IDFError(f"{where}: field Heating Design Capacity and Heating Throttling Range must be > 0")
    if f[9].lower() != "meanairtemperature" or f[10].lower() != "halfflowpower":
        raise IDFError(f"{where}: field Temperature Control Type must be MeanAirTemperature and Setpoint Control "
                       "Type HalfFlowPower (the set point that gives the plant's heat is computed for those)")
    if f[12].lower() not in constants:
        raise IDFError(f"{where}: field Heating Setpoint Temperature Schedule Name: '{f[12]}' is no "
                       "Schedule:Constant (the co-simulation sets it)")
    surf = surfaces.get(f[4].lower())
    if surf is None:
        raise IDFError(f"{where}: field Surface Name: '{f[4]}' is no BuildingSurface:Detailed of the file")
    try:
        area = _surface_area_m2(surf)
    except (ValueError, IndexError):
        raise IDFError(f"{where}: the vertices of surface '{f[4]}' are not numbers") from None
    return Radiant(f[1], f[3], f[4], f[12], capacity, throttling, area)


_DROP = ("runperiod", "site:location", "sizingperiod:designday", "sizingperiod:weatherfileday",
         "sizingperiod:weatherfileconditiontype", "runperiodcontrol:daylightsavingtime")


def run_idf_text(idf_text: str, site: SiteParams, offset_h: float, first_std: pd.Timestamp, days: int) -> str:
    """Replace the IDF's own run period and location by the run's.

    Parameters
    ----------
    idf_text : str
        The IDF.
    site : SiteParams
        Latitude, longitude [deg] and altitude [m].
    offset_h : float
        Standard-time offset from UTC [h].
    first_std : pandas.Timestamp
        Start of the run's first hour, naive local standard time.
    days : int
        Whole days EnergyPlus simulates.

    Returns
    -------
    str
        The IDF without its ``RunPeriod``, ``Site:Location`` and sizing periods, with the run's.
    """
    kept = []
    body = "\n".join(line.split("!", 1)[0] for line in text_lines(idf_text))
    for chunk in body.split(";"):
        head = chunk.split(",", 1)[0].strip().lower()
        if not head or head in _DROP:
            continue
        kept.append(chunk.strip() + ";")
    last = first_std.normalize() + pd.Timedelta(days=days - 1)
    kept.append(f"Site:Location, Karlsruhe, {site.latitude_deg:.6f}, {site.longitude_deg:.6f}, {offset_h:.1f}, "
                f"{site.altitude_m:.1f};")
    kept.append(f"RunPeriod, ComEMS4Build, {first_std.month}, {first_std.day}, {first_std.year}, {last.month}, "
                f"{last.day}, {last.year}, , No, No, No, Yes, Yes, Yes;")
    return "\n".join(kept) + "\n"


@dataclass
class StepRecord:
    """What EnergyPlus received and reported in one step (hourly means over its zone time steps).

    Attributes
    ----------
    q_floor_set_w : float
        Floor heat the plant asked for [W].
    q_floor_received_w : float
        Floor heat EnergyPlus reports the floors received [W].
    gains_w : float
        Appliance load given to the zones' equipment [W] (the IDF decides how much of it is heat).
    solar_w : float
        Sun the windows let into the zones [W].
    internal_w : float
        Internal gains released in the zones [W].
    t_air_c : float
        Floor-area weighted mean air temperature [degC].
    t_zones_c : list of float
        Air temperature of each zone [degC].
    """

    q_floor_set_w: float = 0.0
    q_floor_received_w: float = 0.0
    gains_w: float = 0.0
    solar_w: float = 0.0
    internal_w: float = 0.0
    t_air_c: float = math.nan
    t_zones_c: list[float] = field(default_factory=list)


class EnergyPlusError(RuntimeError):
    """EnergyPlus stopped with an error (its ``eplusout.err`` is named)."""


class EnergyPlusBuilding:
    """The house of an IDF file in EnergyPlus, one plant step per call (see the module docstring).

    Parameters
    ----------
    idf : str or Path or None
        IDF file (None: the shipped German single-family house).
    weather : Weather
        The run's hourly weather (at least ``n_steps`` hours; later rows fill the last day).
    site : SiteParams
        The site (location, time zone).
    n_steps : int
        Steps of the run (1 h each).
    t_air_init_c : float
        The air temperature the warm-up holds [degC].
    workdir : str or Path, optional
        Where EnergyPlus writes its files (default: a temporary folder removed by :meth:`close`).
    epw : str or Path, optional
        An EPW file to use instead of writing one from ``weather`` (checked to cover the run).
    occupants : bool
        False switches the IDF's ``People`` off (steady-state tests without gains).

    Raises
    ------
    IDFError
        If the IDF lacks what the co-simulation needs (:func:`check_idf`).
    EPWError
        If the EPW does not cover the run.
    """

    name = "energyplus"

    def __init__(self, idf: str | Path | None, weather: Weather, site: SiteParams, n_steps: int,
                 t_air_init_c: float, workdir: str | Path | None = None, epw: str | Path | None = None,
                 occupants: bool = True) -> None:
        self.occupants = bool(occupants)
        self.idf = Path(idf) if idf else house.shipped_idf()
        self.spec = check_idf(self.idf)
        self.weather, self.site, self.n_steps = weather, site, int(n_steps)
        self.t_air_init_c = float(t_air_init_c)
        self._own_dir = workdir is None
        self.workdir = Path(tempfile.mkdtemp(prefix="c4b_eplus_")) if workdir is None else Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        offset = standard_offset_h(site, weather.time)
        std = standard_times(weather.time, offset)
        self._first_std = std[0]
        self._skip_hours = int(std[0].hour)
        self._days = int(math.ceil((self.n_steps + self._skip_hours) / 24.0))
        if epw is None:
            self.epw = write_epw(self.workdir / "weather.epw", _full_days(weather, self._days * 24 - self._skip_hours),
                                 site)
        else:
            self.epw = Path(epw)
        check_epw_covers(self.epw, self._first_std, self.n_steps)
        text = run_idf_text(self.idf.read_text(encoding="utf-8"), site, offset, self._first_std, self._days)
        self._run_idf = self.workdir / "run.idf"
        self._run_idf.write_text(text, encoding="utf-8")
        self.last = StepRecord()
        self.records: list[StepRecord] = []
        self._cmd: queue.Queue = queue.Queue()
        self._res: queue.Queue = queue.Queue()
        self._thread: threading.Thread | None = None
        self._api: Any = None
        self._state: Any = None
        self._h: dict[str, Any] = {}
        self._area: dict[str, float] = {}
        self._stop = False
        self._closed = False
        self._rc: int | None = None
        self._acc = StepRecord()
        self._nacc = 0
        self._integral_w = 0.0
        self._hour: tuple[int, int] | None = None
        self._started = False
        self._src_sum = 0.0
        self._solar_sum = 0.0
        self._internal_sum = 0.0
        self._ts_hour = 1
        self._q_flux = 0.0
        self._radiant_w: list[float] = [0.0] * len(self.spec.radiant)
        self._gains_zone = 0.0

    # ----------------------------------------------------------------- protocol
    def initial_temperatures(self, t_air_c: float, t_amb_c: float) -> Temperatures:
        """Start EnergyPlus and return the node temperatures after its warm-up.

        Parameters
        ----------
        t_air_c : float
            The air temperature the warm-up thermostat holds [degC].
        t_amb_c : float
            Not used: the EPW's weather of the first day drives the warm-up [degC].

        Returns
        -------
        Temperatures
            Floor-area weighted zone air temperature, the heated floors' and the exterior walls'
            inside-face temperatures [degC].

        Raises
        ------
        EnergyPlusError
            If EnergyPlus does not start the run.
        """
        self.t_air_init_c = float(t_air_c)
        if self._thread is None:
            self._start()
        kind, payload = self._wait()
        if kind != "init":
            raise EnergyPlusError(f"EnergyPlus did not start the run: {payload}")
        return payload

    def step(self, temps: Temperatures, q_floor_w: float, exo: Exogenous) -> Temperatures:
        """Advance EnergyPlus by one hour with the floor heat and the appliance load of the step.

        Parameters
        ----------
        temps : Temperatures
            Ignored: EnergyPlus keeps its own state [degC].
        q_floor_w : float
            Heat into the floors [W] (negative: cooling).
        exo : Exogenous
            The step's appliance load ``p_load_w`` [W] (the weather is the EPW's).

        Returns
        -------
        Temperatures
            Node temperatures at the hour's end [degC]; :attr:`last` holds the step's record.

        Raises
        ------
        EnergyPlusError
            If EnergyPlus was not started or ended before the step.
        """
        if self._thread is None:
            raise EnergyPlusError("EnergyPlusBuilding.step before initial_temperatures (EnergyPlus not started)")
        self._cmd.put((float(q_floor_w), float(exo.p_load_w)))
        kind, payload = self._wait()
        if kind != "step":
            raise EnergyPlusError(f"EnergyPlus ended before the step: {payload}")
        rec, temps_out = payload
        self.last = rec
        self.records.append(rec)
        return temps_out

    def close(self) -> None:
        """Stop EnergyPlus (if running), join its thread and remove a temporary work folder."""
        if self._closed:
            return
        self._closed = True
        if self._thread is not None and self._thread.is_alive():
            self._stop = True
            self._cmd.put(None)
            self._thread.join(timeout=60)
        if self._api is not None and self._state is not None and not (self._thread and self._thread.is_alive()):
            self._api.state_manager.delete_state(self._state)  # never under a thread still running EnergyPlus
            self._state = None
        if self._own_dir:
            shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> EnergyPlusBuilding:
        """Return the model itself (``with`` closes it)."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Close the model (:meth:`close`)."""
        self.close()

    # ----------------------------------------------------------------- thread
    def _wait(self) -> tuple[str, Any]:
        try:
            return self._res.get(timeout=STEP_TIMEOUT_S)
        except queue.Empty:
            raise EnergyPlusError(f"EnergyPlus gave no result within {STEP_TIMEOUT_S:g} s "
                                  f"(see {self.workdir / 'out' / 'eplusout.err'})") from None

    def _start(self) -> None:
        from pyenergyplus.api import EnergyPlusAPI

        api = self._api = EnergyPlusAPI()
        state = self._state = api.state_manager.new_state()
        api.runtime.set_console_output_status(state, False)
        api.runtime.callback_begin_zone_timestep_after_init_heat_balance(state, self._on_begin)
        api.runtime.callback_begin_system_timestep_before_predictor(state, self._on_system)
        api.runtime.callback_inside_system_iteration_loop(state, self._on_system)
        api.runtime.callback_end_zone_timestep_after_zone_reporting(state, self._on_end)
        for surf in self.spec.floors:
            api.exchange.request_variable(state, SOURCE_VARIABLE, surf)
        for zone in self.spec.zones:
            api.exchange.request_variable(state, "Zone Mean Air Temperature", zone)
            api.exchange.request_variable(state, SOLAR_VARIABLE, zone)
            api.exchange.request_variable(state, INTERNAL_VARIABLE, zone)
        for surf in [*self.spec.floors, *self.spec.exterior_walls]:
            api.exchange.request_variable(state, "Surface Inside Face Temperature", surf)
        for r in self.spec.radiant:
            api.exchange.request_variable(state, RADIANT_VARIABLE, r.name)
            api.exchange.request_variable(state, CONTROL_VARIABLE, r.zone)
        args = ["-w", str(self.epw), "-d", str(self.workdir / "out"), str(self._run_idf)]
        self._thread = threading.Thread(target=self._run, args=(args,), name="energyplus", daemon=True)
        self._thread.start()

    def _run(self, args: list[str]) -> None:
        try:
            self._rc = self._api.runtime.run_energyplus(self._state, args)
        except Exception as exc:  # pragma: no cover - reported to the waiting plant
            self._res.put(("error", f"{type(exc).__name__}: {exc}"))
            return
        err = self.workdir / "out" / "eplusout.err"
        tail = ""
        if err.is_file():
            sev = [line.strip() for line in err.read_text(errors="replace").splitlines() if "** Severe" in line
                   or "**  Fatal" in line]
            tail = "; ".join(sev[:3])
        self._res.put(("end", f"EnergyPlus exited with code {self._rc} ({err}{': ' + tail if tail else ''})"))

    def _handles(self, state: Any) -> bool:
        if self._h:
            return True
        ex = self._api.exchange
        if not ex.api_data_fully_ready(state):
            return False
        h: dict[str, Any] = {
            "flux": ex.get_actuator_handle(state, "Schedule:Constant", "Schedule Value", house.HEAT_SCHEDULE),
            "gains": [ex.get_actuator_handle(state, "ElectricEquipment", "Electricity Rate", a)
                      for a in self.spec.appliances],
            "radiant_sp": [ex.get_actuator_handle(state, "Schedule:Constant", "Schedule Value", r.setpoint)
                           for r in self.spec.radiant],
            "radiant_q": [ex.get_variable_handle(state, RADIANT_VARIABLE, r.name) for r in self.spec.radiant],
            "radiant_mat": [ex.get_variable_handle(state, CONTROL_VARIABLE, r.zone)
                            for r in self.spec.radiant],
            "people": [ex.get_actuator_handle(state, "People", "Number of People", p) for p in self.spec.people]
            if not self.occupants else [],
            "t_zone": [ex.get_variable_handle(state, "Zone Mean Air Temperature", z) for z in self.spec.zones],
            "solar": [ex.get_variable_handle(state, SOLAR_VARIABLE, z) for z in self.spec.zones],
            "internal": [ex.get_variable_handle(state, INTERNAL_VARIABLE, z) for z in self.spec.zones],
            "src": [ex.get_variable_handle(state, SOURCE_VARIABLE, f) for f in self.spec.floors],
            "t_floor": [ex.get_variable_handle(state, "Surface Inside Face Temperature", f) for f in self.spec.floors],
            "t_wall": [ex.get_variable_handle(state, "Surface Inside Face Temperature", w)
                       for w in self.spec.exterior_walls],
            "area_zone": [ex.get_internal_variable_handle(state, "Zone Floor Area", z) for z in self.spec.zones],
        }
        bad = [k for k, v in h.items() if (min(v) if isinstance(v, list) and v else v) == -1]
        if bad:
            self._res.put(("error", f"{self.idf}: EnergyPlus has no handle for {', '.join(bad)}"))
            self._api.runtime.stop_simulation(state)
            return False
        self._h = h
        get = ex.get_internal_variable_value
        self._area = {"floor": list(self.spec.floor_areas_m2), "zone": [get(state, a) for a in h["area_zone"]]}
        return True

    def _t_air(self, state: Any) -> tuple[float, list[float]]:
        ex = self._api.exchange
        temps = [ex.get_variable_value(state, hz) for hz in self._h["t_zone"]]
        w = self._area["zone"]
        return sum(t * a for t, a in zip(temps, w)) / sum(w), temps

    def _set(self, state: Any, q_floor_w: float, gains_w: float) -> None:
        """Heat through the radiant systems (>= 0, split by their surfaces' areas) or the source term (cooling)."""
        ex = self._api.exchange
        rad = self.spec.radiant
        if rad and q_floor_w >= 0.0:
            total = sum(r.area_m2 for r in rad)
            self._radiant_w = [q_floor_w * r.area_m2 / total for r in rad]
            for r, p in zip(rad, self._radiant_w):
                if p > r.capacity_w:
                    raise EnergyPlusError(f"{self.idf}: heat {p:.0f} W above the capacity {r.capacity_w:.0f} W of "
                                          f"'{r.name}'")
            self._q_flux = 0.0
        else:
            self._radiant_w = [0.0] * len(rad)
            self._q_flux = q_floor_w / sum(self._area["floor"])
        ex.set_actuator_value(state, self._h["flux"], self._q_flux)
        per = gains_w / len(self._h["gains"])
        for hg in self._h["gains"]:
            ex.set_actuator_value(state, hg, per)
        for hp in self._h["people"]:
            ex.set_actuator_value(state, hp, 0.0)

    def _on_begin(self, state: Any) -> None:
        self._guard(self._begin, state)

    def _on_end(self, state: Any) -> None:
        self._guard(self._end, state)

    def _on_system(self, state: Any) -> None:
        self._guard(self._system, state)

    def _system(self, state: Any) -> None:
        """Each system time step: the radiant set points from the zones' current air temperature."""
        if self._stop or not self._h or not self.spec.radiant:
            return
        ex = self._api.exchange
        for (r, hs, hm), p in zip(zip(self.spec.radiant, self._h["radiant_sp"], self._h["radiant_mat"]),
                                  self._radiant_w):
            if p > 0.0:
                sp = ex.get_variable_value(state, hm) + (p / r.capacity_w - 0.5) * r.throttling_k
            else:
                sp = RADIANT_OFF_C
            ex.set_actuator_value(state, hs, sp)

    def _guard(self, fn: Any, state: Any) -> None:
        """Run a callback; an exception stops EnergyPlus and reaches the waiting plant (ctypes would drop it)."""
        try:
            fn(state)
        except Exception as exc:
            self._stop = True
            self._res.put(("error", f"co-simulation callback failed: {type(exc).__name__}: {exc}"))
            self._api.runtime.stop_simulation(state)

    def _begin(self, state: Any) -> None:
        if self._stop or not self._handles(state):
            return
        ex = self._api.exchange
        ts_hour = ex.num_time_steps_in_hour(state)
        warm = ex.warmup_flag(state)
        hour_idx = (ex.day_of_year(state), ex.hour(state))
        first_ts = ex.zone_time_step_number(state) == 1
        if warm or (not self._started and ex.hour(state) < self._skip_hours):
            t_air, _ = self._t_air(state)
            err = self.t_air_init_c - t_air
            self._integral_w = min(max(self._integral_w + WARMUP_KI_W_PER_K * err, 0.0), WARMUP_Q_MAX_W)
            q = min(max(WARMUP_KP_W_PER_K * err + self._integral_w, 0.0), WARMUP_Q_MAX_W)
            self._set(state, q, 0.0)
            return
        if first_ts and hour_idx != self._hour:
            if not self._started:
                self._started = True
                self._res.put(("init", self._temps(state)))
            cmd = self._cmd.get()
            if cmd is None:
                self._stop = True
                self._api.runtime.stop_simulation(state)
                return
            self._hour = hour_idx
            self._acc = StepRecord(q_floor_set_w=cmd[0], gains_w=cmd[1])
            self._nacc = 0
            self._src_sum = 0.0
            self._solar_sum = 0.0
            self._internal_sum = 0.0
            self._ts_hour = ts_hour
        self._set(state, self._acc.q_floor_set_w, self._acc.gains_w)

    def _temps(self, state: Any) -> Temperatures:
        ex = self._api.exchange
        t_air, _ = self._t_air(state)
        af = self._area["floor"]
        t_floor = sum(ex.get_variable_value(state, hf) * a for hf, a in zip(self._h["t_floor"], af)) / sum(af)
        walls = [ex.get_variable_value(state, hw) for hw in self._h["t_wall"]]
        t_wall = float(np.mean(walls)) if walls else t_air
        return (t_air, t_floor, t_wall)

    def _end(self, state: Any) -> None:
        if self._stop or not self._h or self._hour is None or self._api.exchange.warmup_flag(state):
            return
        ex = self._api.exchange
        src = sum(ex.get_variable_value(state, hs) * a for hs, a in zip(self._h["src"], self._area["floor"]))
        src += sum(ex.get_variable_value(state, hq) for hq in self._h["radiant_q"])
        self._src_sum += src
        self._solar_sum += sum(ex.get_variable_value(state, h) for h in self._h["solar"])
        self._internal_sum += sum(ex.get_variable_value(state, h) for h in self._h["internal"])
        self._nacc += 1
        if self._nacc == self._ts_hour:
            rec = self._acc
            rec.q_floor_received_w = self._src_sum / self._nacc
            rec.solar_w = self._solar_sum / self._nacc
            rec.internal_w = self._internal_sum / self._nacc
            rec.t_air_c, rec.t_zones_c = self._t_air(state)
            self._res.put(("step", (rec, self._temps(state))))


def _full_days(weather: Weather, hours: int) -> Weather:
    """Return the first ``hours`` rows of ``weather``, the last row repeated where it is shorter."""
    n = len(weather.time)
    idx = np.minimum(np.arange(hours), n - 1)
    time = pd.date_range(weather.time[0], periods=hours, freq="h")
    return Weather(time, np.asarray(weather.t_amb_c)[idx], np.asarray(weather.ghi_w_m2)[idx],
                   np.asarray(weather.dhi_w_m2)[idx])


def weather_of(time: pd.DatetimeIndex, t_amb_c: np.ndarray, ghi_w_m2: np.ndarray, dhi_w_m2: np.ndarray) -> Weather:
    """Build the :class:`~comems4build_ros.core.models.epw.Weather` of a scenario's series.

    Parameters
    ----------
    time : pandas.DatetimeIndex
        Step starts, tz-aware.
    t_amb_c : numpy.ndarray
        Ambient temperature [degC].
    ghi_w_m2, dhi_w_m2 : numpy.ndarray
        Global and diffuse horizontal irradiance [W/m2].

    Returns
    -------
    Weather
        The series as floats.
    """
    return Weather(pd.DatetimeIndex(time), np.asarray(t_amb_c, float), np.asarray(ghi_w_m2, float),
                   np.asarray(dhi_w_m2, float))

