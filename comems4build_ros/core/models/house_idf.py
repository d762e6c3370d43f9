"""The German single-family house of the co-simulation, written as an EnergyPlus input file (IDF).

The house is the TABULA/EPISCOPE type DE.N.SFH.09.Gen (single-family house built
1995-2001, IWU's German residential typology) in its *advanced refurbishment* variant
(DE.N.SFH.09.Gen.ReEx.001.003), made to be the house the paper's 4R3C describes
(``comems4build house`` sets the two side by side). From the typology it takes:

- the reference floor area A_C,ref = 121.9 m2 (here two heated storeys of 60.95 m2 each) and
  TABULA's standard room height of 2.5 m for the air volume,
- the window area as TABULA's ratio window / reference area for the age band (0.266, as
  tabulated in the TEASER archetype of the TABULA DE single-family house), 32.4 m2, facing
  south, east, north and west as the typology's example building's windows (5.0, 3.6, 20.3 and
  3.6 m2),
- TABULA's solar conventions for windows: g_gl,n = 0.5, a frame area fraction F_F = 0.3 and a
  reduction factor for external shading F_sh = 0.6, entered as the whole window's solar heat
  gain coefficient g_gl,n (1 - F_F) F_sh = 0.21 (EnergyPlus adds the angle of incidence),
- the transmission heat transfer coefficient of the variant, H_tr = 87 W/K, which the U-values
  below reproduce to a few per cent (:func:`heat_loss_coefficient` prints the sum),
- airtightness of a refurbished house with mechanical ventilation and heat recovery.

Choices (documented in ``docs/cosimulation.md``): a compact box of 7.81 m x 7.81 m with two
storeys of 2.7 m (floor to floor) and a flat insulated roof; U-values typical of an advanced
refurbishment (wall 0.20 W/m2K, roof 0.14, floor slab 0.25, triple glazing 0.95) with thermal
bridges of 0.05 W/m2K over the envelope put on the wall; infiltration 0.1 1/h (n50 = 1.5 1/h)
and balanced ventilation of 0.4 1/h with 80 % heat recovery, entered as the equivalent
0.08 1/h of outdoor air; floors of 6.5 cm screed on 3 cm insulation (German underfloor
heating, the pipes 3 cm below the screed's top, see below); ground under the slab at the
temperatures of :data:`GROUND_C`.

Construction (:attr:`HouseSpec.construction`): timber frame (sheathed timber-frame walls, a
timber joist storey floor, drywall partitions; the floors keep their screed), chosen so that
the house's effective heat capacity is the 4R3C's (whose capacities come from the identified
house of Sperber, Frey and Bertsch 2020): the masonry variant (sand-lime walls, a concrete
storey slab, masonry partitions) has about twice the capacity (``comems4build house``
measures both the same way: a day's free cool-down).

Internal gains (:attr:`HouseSpec.internal_gains`, default none): as the paper's 4R3C, whose
``eq:dT_i`` has no internal-gain input, the appliance load's electricity reaches the zones'
``ElectricEquipment`` (schedule set each step) with all of its heat lost (``Fraction Lost``
1); with ``internal_gains`` it is released in the zone (30 % radiant) and four occupants are
at home on weekday evenings and nights and all weekend.

Summer (May to September, :attr:`HouseSpec.summer_months`): exterior sun protection (roller
shutters or screens, solar transmittance 0.10) closes on a window whose irradiance exceeds
300 W/m2 (200 W/m2 facing north), the thresholds DIN 4108-2:2013-02 sets for residential
buildings in its simulation of summer thermal protection; the windows open (3 1/h by day,
2 1/h at night) while the room is above 23 degC and warmer than outside (choice, modelled on
that standard's increased day and night ventilation). Outside these months both stay off, so
the winter is untouched.

Heating: per zone an electric low-temperature radiant system (``ZoneHVAC:LowTemperatureRadiant:
Electric``) on the floor, whose heat enters the floor construction at the pipes' level, between
the lower 3.5 cm and the upper 3 cm of the screed (``ConstructionProperty:InternalHeatSource``):
the screed's mass stores it and the floor's surface gives it to the room by convection and
long-wave radiation. Its power follows its set point in the ``HalfFlowPower`` mode (power =
capacity x (set point + range/2 - T_air) / range, clipped to [0, capacity]); the
co-simulation sets the set point each system time step (actuator ``Schedule:Constant`` /
``Schedule Value``) from the zone's current air temperature so that the power is exactly the
plant's heat, and reads back the heat EnergyPlus reports (``Zone Radiant HVAC Heating
Rate``). Cooling (negative heat, the year-round plant) goes through a
``SurfaceProperty:HeatBalanceSourceTerm`` on the floor's top face (schedule in W/m2).

:func:`write_idf` writes the file; the package ships its output as
``comems4build_ros/data/energyplus_house_sfh.idf`` (``python -m
comems4build_ros.core.models.house_idf --write`` regenerates it; a test checks the two
agree).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

#: Names the co-simulation actuates and reads; every IDF given to ``--building energyplus:IDF``
#: must define them (:func:`comems4build_ros.core.models.building_energyplus.check_idf`).
ZONES = ("Ground Floor", "Upper Floor")
FLOORS = ("GF Floor", "UF Floor")
HEAT_SCHEDULE = "C4B Floor Heat Flux"  # Schedule:Constant, W/m2 on each heated floor
GAINS_SCHEDULE = "C4B Appliance Gains"  # Schedule:Constant, W of appliance load per zone
SUMMER_SCHEDULE = "Summer Months"  # sun protection and window ventilation available
WINDOW_DAY_SCHEDULE, WINDOW_NIGHT_SCHEDULE = "Window Ventilation Day", "Window Ventilation Night"
SHADE_MATERIAL = "Exterior Sun Protection"
#: Underfloor heating of each zone: ``ZoneHVAC:LowTemperatureRadiant:Electric`` on the zone's floor,
#: whose heat enters the screed at the pipes' level (``ConstructionProperty:InternalHeatSource``).
RADIANT = ("GF Floor Heating", "UF Floor Heating")
#: Its set-point schedules (Schedule:Constant), which the co-simulation sets so that the heating
#: delivers exactly the plant's heat (:data:`RADIANT_THROTTLING_K`, :data:`RADIANT_CAPACITY_W`).
RADIANT_SETPOINTS = ("C4B GF Floor Heating Setpoint", "C4B UF Floor Heating Setpoint")
#: Heating capacity of each floor's system [W] (above the heat pump's largest heat) and its
#: throttling range [K] (``HalfFlowPower``: power = capacity x (set point + range/2 - T_air) / range).
RADIANT_CAPACITY_W = 20000.0
RADIANT_THROTTLING_K = 2.0

#: Monthly ground temperature under the slab [degC], January .. December (choice: the DWD
#: Rheinstetten annual mean of 11 degC damped and delayed under a heated house, ISO 13370-like).
GROUND_C = (10.0, 9.5, 9.5, 10.0, 11.0, 12.0, 13.0, 13.5, 13.5, 13.0, 12.0, 11.0)


@dataclass(frozen=True)
class Layer:
    """One material layer of a construction.

    Attributes
    ----------
    name : str
        The material's name in the IDF.
    thickness_m : float
        Thickness [m].
    k_w_mk : float
        Thermal conductivity [W/(m K)].
    rho_kg_m3 : float
        Density [kg/m3].
    c_j_kgk : float
        Specific heat capacity [J/(kg K)].
    """

    name: str
    thickness_m: float
    k_w_mk: float
    rho_kg_m3: float
    c_j_kgk: float

    @property
    def r_m2k_w(self) -> float:
        """Thermal resistance [m2 K/W]."""
        return self.thickness_m / self.k_w_mk


@dataclass(frozen=True)
class HouseSpec:
    """Geometry and envelope of the house (TABULA DE.N.SFH.09.Gen, advanced refurbishment; SI units).

    Attributes
    ----------
    width_m, depth_m, storey_m : float
        Outer width (east-west), depth (north-south) and floor-to-floor height [m].
    window_ratio : float
        Window area over the heated floor area [-] (TABULA).
    window_share : tuple of float
        Shares of the window area facing south, east, north, west [-].
    window_height_m, sill_m : float
        Window height and sill height [m].
    u_window : float
        Window U-value [W/(m2 K)].
    g_window : float
        Window solar heat gain coefficient [-].
    u_wall_target, u_roof_target, u_floor_target : float
        U-value targets of wall, roof and ground slab [W/(m2 K)].
    du_thermal_bridge : float
        Thermal-bridge surcharge over the envelope [W/(m2 K)].
    infiltration_ach, ventilation_ach : float
        Infiltration and balanced ventilation air change [1/h].
    heat_recovery : float
        Share of the ventilation's heat recovered [-].
    b_ground : float
        TABULA's adjustment factor of a floor on the ground [-].
    occupants : int
        Occupants.
    timesteps_per_hour : int
        EnergyPlus zone time steps per hour.
    """

    width_m: float = 7.81           # east-west
    depth_m: float = 7.81           # north-south: 2 x 7.81^2 = 121.99 m2 = TABULA A_C,ref 121.9 m2
    storey_m: float = 2.7           # floor to floor
    room_height_m: float = 2.5      # clear room height of the air volume (TABULA's standard room height)
    window_ratio: float = 0.266     # TABULA window area / reference floor area, 1995-2001 (TEASER archetype)
    #: Share of the window area facing S, E, N, W: TABULA's example building of the type has 5.0, 3.6,
    #: 20.3 and 3.6 m2 there (32.5 m2 in all).
    window_share: tuple[float, float, float, float] = (5.0 / 32.5, 3.6 / 32.5, 20.3 / 32.5, 3.6 / 32.5)
    window_height_m: float = 1.4
    sill_m: float = 0.9
    u_window: float = 0.95          # triple glazing, W/(m2 K) (choice, advanced refurbishment)
    g_window: float = 0.5           # g-value of the glazing at normal incidence, g_gl,n (choice)
    frame_fraction: float = 0.3     # TABULA's frame area fraction F_F of a window
    shading_factor: float = 0.6     # TABULA's reduction factor of external shading F_sh (vertical, heating season)
    u_wall_target: float = 0.20     # advanced refurbishment (choice)
    u_roof_target: float = 0.14
    u_floor_target: float = 0.25
    du_thermal_bridge: float = 0.05  # W/(m2 K) over the envelope, put on the wall (choice)
    construction: str = "timber_frame"  # or "masonry" (CONSTRUCTIONS; choice: the 4R3C's capacity, see above)
    exterior_solar_absorptance: float = 0.6  # render of the walls and the roof's outer layer (choice)
    infiltration_ach: float = 0.1    # n50 = 1.5 1/h divided by 15 (choice)
    ventilation_ach: float = 0.4     # balanced ventilation (choice)
    heat_recovery: float = 0.8       # of the ventilation's heat (choice)
    b_ground: float = 0.5            # TABULA's adjustment factor of a floor on the ground
    internal_gains: bool = False     # appliance heat and occupants in the zones (False: none, as eq:dT_i)
    occupants: int = 4               # with internal_gains only
    summer_months: tuple[int, int] = (5, 9)  # sun protection and window ventilation, May..September (choice)
    sun_protection_w_m2: float = 300.0        # exterior shades close above this on the window (DIN 4108-2)
    sun_protection_north_w_m2: float = 200.0  # the same facing north (DIN 4108-2)
    shade_transmittance: float = 0.10         # exterior roller shutter / screen, solar (choice)
    shade_reflectance: float = 0.50
    window_ach_day: float = 3.0      # window ventilation 6-23 h [1/h] (choice after DIN 4108-2)
    window_ach_night: float = 2.0    # window ventilation 23-6 h [1/h] (choice after DIN 4108-2)
    window_open_above_c: float = 23.0  # windows open when the room is above this and warmer than outside
    timesteps_per_hour: int = 4      # zone time step 15 min

    @property
    def floor_m2(self) -> float:
        """Floor area of one storey [m2]."""
        return self.width_m * self.depth_m

    @property
    def heated_floor_m2(self) -> float:
        """Heated floor area, both storeys [m2]."""
        return 2 * self.floor_m2

    @property
    def volume_m3(self) -> float:
        """Air volume [m3]: the heated floor area times the clear room height (each zone's ``Volume``)."""
        return self.heated_floor_m2 * self.room_height_m

    @property
    def window_m2(self) -> float:
        """Window area of the house [m2]."""
        return self.window_ratio * self.heated_floor_m2

    @property
    def wall_gross_m2(self) -> float:
        """Exterior wall area including windows [m2]."""
        return 2 * (self.width_m + self.depth_m) * 2 * self.storey_m

    @property
    def g_effective(self) -> float:
        """Solar heat gain coefficient of the whole window as entered: g_gl,n (1 - F_F) F_sh [-] (TABULA)."""
        return self.g_window * (1.0 - self.frame_fraction) * self.shading_factor

    @property
    def solar_aperture_m2(self) -> float:
        """Window area times its effective g-value [m2] (before the incidence angle and the sun protection)."""
        return self.window_m2 * self.g_effective

    @property
    def air_ach(self) -> float:
        """Outdoor air change equivalent to infiltration plus ventilation after heat recovery [1/h]."""
        return self.infiltration_ach + self.ventilation_ach * (1.0 - self.heat_recovery)


PLASTER_EXT = Layer("Exterior plaster", 0.02, 0.87, 1800.0, 1000.0)
PLASTER_INT = Layer("Gypsum plaster", 0.015, 0.70, 1400.0, 1000.0)
CONCRETE = Layer("Concrete slab", 0.16, 2.1, 2400.0, 1000.0)
IMPACT_INS = Layer("Impact sound insulation", 0.03, 0.04, 30.0, 1400.0)
SCREED_LOW = Layer("Cement screed below the pipes", 0.035, 1.4, 2000.0, 1000.0)
SCREED_TOP = Layer("Cement screed above the pipes", 0.030, 1.4, 2000.0, 1000.0)
TILES = Layer("Floor tiles", 0.01, 1.3, 2300.0, 840.0)
TIMBER = Layer("Timber boarding", 0.024, 0.13, 500.0, 1600.0)
GYPSUM = Layer("Gypsum board", 0.0125, 0.25, 900.0, 1000.0)
#: Masonry construction (:attr:`HouseSpec.construction` ``"masonry"``): sand-lime walls, concrete storey
#: slab, masonry partitions.
SANDLIME = Layer("Sand-lime masonry", 0.175, 0.99, 1800.0, 1000.0)
PARTITION = Layer("Partition masonry half", 0.0575, 0.99, 1800.0, 1000.0)
#: Timber-frame construction (``"timber_frame"``, the default): sheathed timber-frame walls, a timber
#: joist storey floor, drywall partitions; the floors keep their screed for the underfloor heating.
#: Values of EN ISO 10456 (OSB, gypsum boards) and a joist layer of 15 % timber and 85 % mineral wool.
OSB = Layer("Wall sheathing OSB", 0.015, 0.13, 650.0, 1700.0)
GYPSUM_FIBRE = Layer("Gypsum fibre board", 0.025, 0.32, 1150.0, 1100.0)
JOISTS = Layer("Timber joists with mineral wool", 0.22, 0.0535, 100.0, 1500.0)
FLOOR_BOARDS = Layer("Floor boarding", 0.022, 0.13, 500.0, 1600.0)
DRYWALL_HALF = Layer("Partition drywall half", 0.025, 0.25, 900.0, 1000.0)
#: The constructions' choices: the effective heat capacity of the house (``comems4build house``
#: measures it) follows from them.
CONSTRUCTIONS = ("timber_frame", "masonry")

#: Solar absorptance of every other material's faces (choice).
INTERIOR_SOLAR_ABSORPTANCE = 0.6

#: Surface film resistances [m2 K/W] (EN ISO 6946): outside, inside horizontal flow, upward, downward.
R_SE, R_SI_WALL, R_SI_UP, R_SI_DOWN = 0.04, 0.13, 0.10, 0.17


def _insulation(name: str, r_needed: float) -> Layer:
    """Insulation (k = 0.035 W/(m K)) of the thickness that gives ``r_needed`` [m2 K/W]."""
    return Layer(name, round(r_needed * 0.035, 4), 0.035, 30.0, 1400.0)


def constructions(spec: HouseSpec) -> dict[str, list[Layer]]:
    """Build the layers of each construction, outside to inside (floors: bottom to top), sized to the U-value targets.

    Parameters
    ----------
    spec : HouseSpec
        The house.

    Returns
    -------
    dict of str to list of Layer
        Construction name -> layers (insulation thickness from the U-value target, film
        resistances of EN ISO 6946).
    """
    if spec.construction not in CONSTRUCTIONS:
        raise ValueError(f"HouseSpec.construction: {spec.construction!r} is none of {', '.join(CONSTRUCTIONS)}")
    masonry = spec.construction == "masonry"
    area_env = spec.wall_gross_m2 + 2 * spec.floor_m2
    wall_net = spec.wall_gross_m2 - spec.window_m2
    u_wall = spec.u_wall_target + spec.du_thermal_bridge * area_env / wall_net
    wall_inner = [SANDLIME, PLASTER_INT] if masonry else [OSB, GYPSUM_FIBRE]
    r_wall = 1.0 / u_wall - R_SE - R_SI_WALL - sum(x.r_m2k_w for x in [PLASTER_EXT, *wall_inner])
    roof_rest = [TIMBER, GYPSUM]
    r_roof = 1.0 / spec.u_roof_target - R_SE - R_SI_UP - sum(x.r_m2k_w for x in roof_rest)
    slab_rest = [CONCRETE, IMPACT_INS, SCREED_LOW, SCREED_TOP, TILES]
    r_floor = 1.0 / spec.u_floor_target - R_SI_DOWN - sum(x.r_m2k_w for x in slab_rest)
    storey = [PLASTER_INT, CONCRETE] if masonry else [GYPSUM, JOISTS, FLOOR_BOARDS]
    storey += [IMPACT_INS, SCREED_LOW, SCREED_TOP, TILES]
    return {
        "Exterior Wall": [PLASTER_EXT, _insulation("Wall insulation", r_wall), *wall_inner],
        "Roof": [TIMBER, _insulation("Roof insulation", r_roof), GYPSUM],
        "Ground Slab": [_insulation("Perimeter insulation", r_floor), *slab_rest],
        "Storey Floor": storey,
        "Storey Ceiling": storey[::-1],
        "Partitions": [PLASTER_INT, PARTITION] if masonry else [DRYWALL_HALF],
    }


def source_layer(layers: list[Layer]) -> int:
    """Return the number of the layer after which a heated floor's pipes sit (1-based, bottom up).

    The pipes sit below the top screed.
    """
    return [x.name for x in layers].index(SCREED_LOW.name) + 1


#: Exposed area of the partitions (both faces) per storey's floor area (choice).
PARTITION_AREA_PER_FLOOR = 1.5
#: Volumetric heat capacity of air [J/(m3 K)] (1.2 kg/m3 x 1006 J/(kg K)).
AIR_J_PER_M3K = 1207.0


def heat_capacity(spec: HouseSpec | None = None) -> dict[str, float]:
    """Heat capacity of the house's air and constructions, sum of rho c d A over every layer [J/K].

    Returns
    -------
    dict with ``air``, ``walls``, ``roof``, ``ground_slab``, ``storey_floor``, ``partitions`` and their
    sum ``total`` [J/K] (the storey floor once: its ceiling face is the same slab).
    """
    spec = spec or HouseSpec()
    c = constructions(spec)

    def per_m2(name: str) -> float:
        return sum(x.thickness_m * x.rho_kg_m3 * x.c_j_kgk for x in c[name])

    parts = {
        "air": AIR_J_PER_M3K * spec.volume_m3,
        "walls": per_m2("Exterior Wall") * (spec.wall_gross_m2 - spec.window_m2),
        "roof": per_m2("Roof") * spec.floor_m2,
        "ground_slab": per_m2("Ground Slab") * spec.floor_m2,
        "storey_floor": per_m2("Storey Floor") * spec.floor_m2,
        "partitions": per_m2("Partitions") * PARTITION_AREA_PER_FLOOR * spec.heated_floor_m2,
    }
    return {**parts, "total": sum(parts.values())}


def u_value(layers: list[Layer], r_films: float) -> float:
    """Compute the U-value of a construction (EN ISO 6946: 1 / (R_films + sum of layer resistances)).

    Parameters
    ----------
    layers : list of Layer
        The construction's layers.
    r_films : float
        Sum of the surface film resistances [m2 K/W].

    Returns
    -------
    float
        U-value [W/(m2 K)].
    """
    return 1.0 / (r_films + sum(x.r_m2k_w for x in layers))


def heat_loss_coefficient(spec: HouseSpec | None = None) -> dict[str, float]:
    """Compute the house's steady-state heat loss coefficient by the typology's method.

    H = sum(U A b) + H_ve with b = 1 towards the outdoor air and ``b_ground`` towards the
    ground (TABULA), H_ve = rho c_p n V = 0.34 Wh/(m3 K) * n * V.

    Parameters
    ----------
    spec : HouseSpec, optional
        The house (default :class:`HouseSpec`).

    Returns
    -------
    dict of str to float
        ``h_tr_w_per_k``, ``h_ve_w_per_k``, ``h_w_per_k`` and the parts ``wall``,
        ``window``, ``roof``, ``floor`` [W/K].
    """
    spec = spec or HouseSpec()
    c = constructions(spec)
    wall_net = spec.wall_gross_m2 - spec.window_m2
    parts = {
        "wall": u_value(c["Exterior Wall"], R_SE + R_SI_WALL) * wall_net,
        "window": spec.u_window * spec.window_m2,
        "roof": u_value(c["Roof"], R_SE + R_SI_UP) * spec.floor_m2,
        "floor": u_value(c["Ground Slab"], R_SI_DOWN) * spec.floor_m2 * spec.b_ground,
    }
    h_tr = sum(parts.values())
    h_ve = 0.34 * spec.air_ach * spec.volume_m3
    return {"h_tr_w_per_k": h_tr, "h_ve_w_per_k": h_ve, "h_w_per_k": h_tr + h_ve, **parts}


def _obj(kind: str, *fields: object, comment: str = "") -> str:
    """One IDF object: ``Kind,`` then one field per line, the last ending in ``;``."""
    head = f"! {comment}\n" if comment else ""
    vals = [_fmt(f) for f in fields]
    lines = [f"{kind},"] + [f"  {v}{';' if i == len(vals) - 1 else ','}" for i, v in enumerate(vals)]
    return head + "\n".join(lines) + "\n"


def _fmt(value: object) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


def _surface(name: str, kind: str, construction: str, zone: str, boundary: str, boundary_obj: str,
             sun: bool, pts: list[tuple[float, float, float]]) -> str:
    coords: list[object] = []
    for p in pts:
        coords.extend(round(v, 4) for v in p)
    return _obj("BuildingSurface:Detailed", name, kind, construction, zone, "", boundary, boundary_obj,
                "SunExposed" if sun else "NoSun", "WindExposed" if sun else "NoWind", "autocalculate",
                len(pts), *coords)


def _wall_points(side: str, w: float, d: float, z0: float, z1: float) -> list[tuple[float, float, float]]:
    """Wall corners counter-clockwise seen from outside, upper left first."""
    corners = {
        "South": ((0, 0), (w, 0)),
        "East": ((w, 0), (w, d)),
        "North": ((w, d), (0, d)),
        "West": ((0, d), (0, 0)),
    }
    (xa, ya), (xb, yb) = corners[side]
    return [(xa, ya, z1), (xa, ya, z0), (xb, yb, z0), (xb, yb, z1)]


def _window_points(side: str, spec: HouseSpec, z0: float, area: float) -> list[tuple[float, float, float]]:
    """Return a window centred in the wall ``side`` of the storey starting at ``z0``."""
    length = spec.width_m if side in ("South", "North") else spec.depth_m
    width = area / spec.window_height_m
    a = (length - width) / 2.0
    zb, zt = z0 + spec.sill_m, z0 + spec.sill_m + spec.window_height_m
    (xa, ya, _), _, (xb, yb, _), _ = _wall_points(side, spec.width_m, spec.depth_m, z0, z0)
    ux, uy = (xb - xa) / length, (yb - ya) / length
    p0 = (xa + ux * a, ya + uy * a)
    p1 = (xa + ux * (a + width), ya + uy * (a + width))
    return [(p0[0], p0[1], zt), (p0[0], p0[1], zb), (p1[0], p1[1], zb), (p1[0], p1[1], zt)]


HEADER = """! ComEMS4Build co-simulation house: German single-family house, TABULA DE.N.SFH.09.Gen
! (built 1995-2001), advanced refurbishment (DE.N.SFH.09.Gen.ReEx.001.003), two heated storeys,
! underfloor heating into the screed (electric radiant system, internal heat source). Written by
! comems4build_ros.core.models.house_idf (sources and choices in its docstring and in
! docs/cosimulation.md). The co-simulation adds RunPeriod, Site:Location and the weather file.
! Heat loss coefficient (typology method): H_tr = {h_tr:.1f} W/K, H_ve = {h_ve:.1f} W/K, H = {h:.1f} W/K.
! Construction: {construction}; internal gains: {gains}; sun protection and window ventilation in months {summer}.
"""


def idf_text(spec: HouseSpec | None = None) -> str:
    """Write the house as IDF text for EnergyPlus 25.2 (without RunPeriod and Site:Location).

    Parameters
    ----------
    spec : HouseSpec, optional
        The house (default :class:`HouseSpec`).

    Returns
    -------
    str
        The IDF.
    """
    spec = spec or HouseSpec()
    h = heat_loss_coefficient(spec)
    out = [HEADER.format(h_tr=h["h_tr_w_per_k"], h_ve=h["h_ve_w_per_k"], h=h["h_w_per_k"],
                         construction=spec.construction.replace("_", " "),
                         gains="appliances and occupants" if spec.internal_gains else "none (as eq:dT_i)",
                         summer="{}-{}".format(*spec.summer_months))]
    out += _simulation_objects(spec)
    out += _construction_objects(spec)
    for i, zone in enumerate(ZONES):
        out += _zone_objects(spec, i, zone)
    return "".join(o if o.endswith("\n") else o + "\n" for o in out)


def _simulation_objects(spec: HouseSpec) -> list[str]:
    """Version, run control, ground temperature and the schedules the co-simulation sets."""
    out: list[str] = []
    out.append(_obj("Version", "25.2"))
    out.append(_obj("SimulationControl", "No", "No", "No", "No", "Yes", "No", 1))
    out.append(_obj("Building", "TABULA DE.N.SFH.09.Gen advanced", 0.0, "Suburbs", 0.04, 0.4,
                    "FullInteriorAndExterior", 25, 6))
    out.append(_obj("Timestep", spec.timesteps_per_hour))
    out.append(_obj("GlobalGeometryRules", "UpperLeftCorner", "Counterclockwise", "Relative"))
    out.append(_obj("Site:GroundTemperature:BuildingSurface", *[float(t) for t in GROUND_C],
                    comment="ground under the slab (choice, docstring)"))
    out.append(_obj("ScheduleTypeLimits", "Any Number"))
    out.append(_obj("ScheduleTypeLimits", "Fraction", 0.0, 1.0, "Continuous"))
    out.append(_obj("Schedule:Constant", HEAT_SCHEDULE, "Any Number", 0.0,
                    comment="floor heat flux [W/m2], set each zone time step by the co-simulation"))
    out.append(_obj("Schedule:Constant", GAINS_SCHEDULE, "Any Number", 0.0,
                    comment="appliance load per zone [W], set each zone time step by the co-simulation"))
    out.append(_obj("Schedule:Constant", "Always On", "Fraction", 1.0))
    if spec.internal_gains:
        out.append(_obj("Schedule:Compact", "Occupancy", "Fraction",
                        "Through: 12/31", "For: Weekdays", "Until: 08:00", 1.0, "Until: 17:00", 0.0,
                        "Until: 24:00", 1.0, "For: AllOtherDays", "Until: 24:00", 1.0,
                        comment="at home on weekday evenings and nights and all weekend (eq:T_min's presence)"))
        out.append(_obj("Schedule:Constant", "Activity", "Any Number", 100.0))
    first, last = spec.summer_months
    before, end = _month_end(first - 1), _month_end(last)
    out.append(_obj("Schedule:Compact", SUMMER_SCHEDULE, "Fraction",
                    f"Through: {before}", "For: AllDays", "Until: 24:00", 0.0,
                    f"Through: {end}", "For: AllDays", "Until: 24:00", 1.0,
                    "Through: 12/31", "For: AllDays", "Until: 24:00", 0.0,
                    comment="the summer months: sun protection and window ventilation available (choice)"))
    for name, day in ((WINDOW_DAY_SCHEDULE, True), (WINDOW_NIGHT_SCHEDULE, False)):
        on, off = (1.0, 0.0) if day else (0.0, 1.0)
        out.append(_obj("Schedule:Compact", name, "Fraction",
                        f"Through: {before}", "For: AllDays", "Until: 24:00", 0.0,
                        f"Through: {end}", "For: AllDays", "Until: 06:00", off, "Until: 23:00", on,
                        "Until: 24:00", off,
                        "Through: 12/31", "For: AllDays", "Until: 24:00", 0.0,
                        comment=f"window ventilation by {'day (6-23 h)' if day else 'night (23-6 h)'} in summer"))
    return out


def _month_end(month: int) -> str:
    """``M/D`` of the last day of ``month`` (1..12) in a non-leap year, for Schedule:Compact."""
    days = (31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31)
    return f"{month}/{days[month - 1]}"


def _construction_objects(spec: HouseSpec) -> list[str]:
    """Materials, glazing and constructions (the floors with the heating's pipes in the screed)."""
    out: list[str] = []
    mats = {}
    for layers in constructions(spec).values():
        for x in layers:
            mats[x.name] = x
    c = constructions(spec)
    outer = {c["Exterior Wall"][0].name, c["Roof"][0].name}
    for x in mats.values():
        alpha = spec.exterior_solar_absorptance if x.name in outer else INTERIOR_SOLAR_ABSORPTANCE
        out.append(_obj("Material", x.name, "MediumRough", x.thickness_m, x.k_w_mk, x.rho_kg_m3, x.c_j_kgk,
                        0.9, alpha, alpha))
    out.append(_obj("WindowMaterial:SimpleGlazingSystem", "Triple Glazing", spec.u_window, spec.g_effective, "",
                    comment="whole-window SHGC g_gl,n (1 - F_F) F_sh (TABULA's frame and shading factors)"))
    out.append(_obj("WindowMaterial:Shade", SHADE_MATERIAL, spec.shade_transmittance, spec.shade_reflectance,
                    spec.shade_transmittance, spec.shade_reflectance, 0.9, 0.0, 0.01, 0.1, 0.05,
                    0.5, 0.5, 0.5, 0.5, 0.0,
                    comment="exterior sun protection (roller shutter / screen), closed by the shading control"))
    for name, layers in constructions(spec).items():
        out.append(_obj("Construction", name, *[x.name for x in layers]))
    for name in ("Ground Slab", "Storey Floor"):
        n = source_layer(constructions(spec)[name])
        out.append(_obj("ConstructionProperty:InternalHeatSource", f"{name} Pipes", name, n, n, 1, 0.15, 0.0,
                        comment="the floor heating's pipes in the screed"))
    out.append(_obj("Construction", "Window", "Triple Glazing"))
    return out


def _zone_objects(spec: HouseSpec, i: int, zone: str) -> list[str]:
    """Storey ``i`` (zone ``zone``): its surfaces, windows, floor heating, gains and air change."""
    out: list[str] = []
    w, d, hs = spec.width_m, spec.depth_m, spec.storey_m
    sides = ("South", "East", "North", "West")
    z0, z1 = i * hs, (i + 1) * hs
    tag = "GF" if i == 0 else "UF"
    out.append(_obj("Zone", zone, 0, 0, 0, 0, 1, 1, "autocalculate", spec.floor_m2 * spec.room_height_m))
    for side, share in zip(sides, spec.window_share):
        wall = f"{tag} {side} Wall"
        out.append(_surface(wall, "Wall", "Exterior Wall", zone, "Outdoors", "", True,
                            _wall_points(side, w, d, z0, z1)))
        pts = _window_points(side, spec, z0, spec.window_m2 * share / 2.0)
        coords: list[object] = []
        for p in pts:
            coords.extend(round(v, 4) for v in p)
        out.append(_obj("FenestrationSurface:Detailed", f"{tag} {side} Window", "Window", "Window", wall, "",
                        "autocalculate", "", 1.0, 4, *coords))
    floor_pts = [(w, 0, z0), (0, 0, z0), (0, d, z0), (w, d, z0)]
    top_pts = [(0, 0, z1), (w, 0, z1), (w, d, z1), (0, d, z1)]
    if i == 0:
        out.append(_surface(FLOORS[0], "Floor", "Ground Slab", zone, "Ground", "", False, floor_pts))
        out.append(_surface("GF Ceiling", "Ceiling", "Storey Ceiling", zone, "Surface", FLOORS[1], False,
                            top_pts))
    else:
        out.append(_surface(FLOORS[1], "Floor", "Storey Floor", zone, "Surface", "GF Ceiling", False, floor_pts))
        out.append(_surface("UF Roof", "Roof", "Roof", zone, "Outdoors", "", True, top_pts))
    out.append(_obj("InternalMass", f"{tag} Partitions", "Partitions", zone, "",
                    PARTITION_AREA_PER_FLOOR * spec.floor_m2,
                    comment="partition walls and furniture, both faces (choice)"))
    out.append(_obj("SurfaceProperty:HeatBalanceSourceTerm", FLOORS[i], HEAT_SCHEDULE, "",
                    comment="cooling through the floor (negative heat) at its top face"))
    out.append(_obj("Schedule:Constant", RADIANT_SETPOINTS[i], "Any Number", -100.0,
                    comment="set point of the floor heating, set each system time step by the co-simulation"))
    out.append(_obj("ZoneHVAC:LowTemperatureRadiant:Electric", RADIANT[i], "Always On", zone, FLOORS[i],
                    "HeatingDesignCapacity", RADIANT_CAPACITY_W, "", "", "MeanAirTemperature", "HalfFlowPower",
                    RADIANT_THROTTLING_K, RADIANT_SETPOINTS[i],
                    comment="underfloor heating: the heat pump's heat into the screed at the pipes"))
    out.append(_obj("ZoneHVAC:EquipmentConnections", zone, f"{tag} Equipment", "", "", f"{tag} Air Node",
                    f"{tag} Return Node"))
    out.append(_obj("ZoneHVAC:EquipmentList", f"{tag} Equipment", "SequentialLoad",
                    "ZoneHVAC:LowTemperatureRadiant:Electric", RADIANT[i], 1, 1, "", ""))
    radiant, lost = (0.3, 0.0) if spec.internal_gains else (0.0, 1.0)
    out.append(_obj("ElectricEquipment", f"{tag} Appliances", zone, GAINS_SCHEDULE, "EquipmentLevel", 1.0,
                    "", "", 0.0, radiant, lost,
                    comment="the appliance load; its heat in the zone with internal_gains, else lost (eq:dT_i)"))
    if spec.internal_gains:
        out.append(_obj("People", f"{tag} Occupants", zone, "Occupancy", "People", spec.occupants / 2, "", "",
                        0.3, "autocalculate", "Activity"))
    out.append(_obj("ZoneInfiltration:DesignFlowRate", f"{tag} Air Change", zone, "Always On", "AirChanges/Hour",
                    "", "", "", spec.air_ach, 1.0, 0.0, 0.0, 0.0,
                    comment="infiltration + ventilation after heat recovery (choice)"))
    for seq, (label, sides, limit) in enumerate(
            (("Sun Protection", ("South", "East", "West"), spec.sun_protection_w_m2),
             ("Sun Protection North", ("North",), spec.sun_protection_north_w_m2)), start=1):
        out.append(_obj("WindowShadingControl", f"{tag} {label}", zone, seq, "ExteriorShade", "",
                        "OnIfHighSolarOnWindow", SUMMER_SCHEDULE, limit, "Yes", "No", SHADE_MATERIAL,
                        "FixedSlatAngle", "", "", "", "Group", *[f"{tag} {side} Window" for side in sides],
                        comment="sun protection closed above the irradiance on the window, in summer (DIN 4108-2)"))
    for label, sched, ach in (("Window Ventilation Day", WINDOW_DAY_SCHEDULE, spec.window_ach_day),
                              ("Window Ventilation Night", WINDOW_NIGHT_SCHEDULE, spec.window_ach_night)):
        out.append(_obj("ZoneVentilation:DesignFlowRate", f"{tag} {label}", zone, sched, "AirChanges/Hour",
                        "", "", "", ach, "Natural", 0.0, 1.0, 1.0, 0.0, 0.0, 0.0,
                        spec.window_open_above_c, "", 100.0, "", 0.0, "", -100.0, "", 100.0, "", 40.0,
                        comment="open windows in summer when the room is warm and warmer than outside"))
    return out


def shipped_idf() -> Path:
    """Return the path of the IDF the package ships (``comems4build_ros/data/energyplus_house_sfh.idf``)."""
    return Path(__file__).resolve().parents[2] / "data" / "energyplus_house_sfh.idf"


def write_idf(path: str | Path, spec: HouseSpec | None = None) -> Path:
    """Write the house's IDF to ``path``.

    Parameters
    ----------
    path : str or Path
        Output file.
    spec : HouseSpec, optional
        The house (default :class:`HouseSpec`).

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    path.write_text(idf_text(spec), encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    """Run ``python -m comems4build_ros.core.models.house_idf [--write]``: print the heat loss coefficient.

    Parameters
    ----------
    argv : list of str, optional
        Arguments (default ``sys.argv[1:]``); ``--write`` regenerates the shipped IDF.

    Returns
    -------
    int
        Exit code 0.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="regenerate the shipped IDF")
    args = parser.parse_args(argv)
    if args.write:
        print(f"wrote {write_idf(shipped_idf())}")
    for key, value in heat_loss_coefficient().items():
        print(f"{key}: {value:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
