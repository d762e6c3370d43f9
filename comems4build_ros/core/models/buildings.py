"""Which building model a run uses: ``--building rc | energyplus[:IDF] | fmu:PATH``.

:func:`parse_building` reads the option, :func:`check_building` checks its files before
anything runs (a broken IDF, an FMU that does not load, a variable map naming a variable the
FMU lacks: :class:`BuildingChoiceError` naming the file and the field), and
:func:`make_building` builds the model for a run:

- ``rc``: the paper's 4R3C (:class:`~comems4build_ros.core.models.building.RCBuilding`),
  the default; runs with it are the runs without the option, bit for bit;
- ``energyplus`` or ``energyplus:FILE.idf``: the house in EnergyPlus
  (:class:`~comems4build_ros.core.models.building_energyplus.EnergyPlusBuilding`), by
  default the shipped German single-family house;
- ``fmu:FILE.fmu``: an FMI 2.0 co-simulation FMU
  (:class:`~comems4build_ros.core.models.building_fmu.FMUBuilding`) with the variable map
  ``FILE.map.yaml`` beside it or the one given (``--building-map``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from comems4build_ros.core.config import PlantParams
from comems4build_ros.core.models.building import BuildingModel, RCBuilding
from comems4build_ros.core.models.epw import Weather
from comems4build_ros.files.errors import InputError

#: Kinds of building model.
KINDS = ("rc", "energyplus", "fmu")


class BuildingChoiceError(InputError):
    """A ``--building`` value or one of its files that cannot serve a run."""


@dataclass(frozen=True)
class BuildingChoice:
    """A parsed ``--building`` value.

    Attributes
    ----------
    kind : str
        ``rc``, ``energyplus`` or ``fmu``.
    path : Path or None
        The IDF or FMU (None: the shipped house, or none for ``rc``).
    map_path : Path or None
        The FMU's variable map (``fmu`` only).
    epw : Path or None
        An EPW file to use instead of the one written from the scenario (``energyplus`` only).
    """

    kind: str = "rc"
    path: Path | None = None
    map_path: Path | None = None
    epw: Path | None = None

    @property
    def text(self) -> str:
        """The option's text: ``rc``, ``energyplus``, ``energyplus:house.idf`` or ``fmu:x.fmu``."""
        return self.kind if self.path is None else f"{self.kind}:{self.path}"


def parse_building(text: str | None, map_path: str | Path | None = None,
                   epw: str | Path | None = None) -> BuildingChoice:
    """Parse ``rc``, ``energyplus[:IDF]`` or ``fmu:PATH`` into a :class:`BuildingChoice`.

    Parameters
    ----------
    text : str or None
        The ``--building`` value (None: ``rc``).
    map_path : str or Path, optional
        ``--building-map`` (``fmu`` only; default the map beside the FMU).
    epw : str or Path, optional
        ``--epw`` (``energyplus`` only).

    Returns
    -------
    BuildingChoice
        The parsed choice (files not yet read: :func:`check_building`).

    Raises
    ------
    BuildingChoiceError
        For an unknown kind, a file where none belongs or a missing one, naming the option.
    """
    text = (text or "rc").strip()
    kind, _, path = text.partition(":")
    if kind not in KINDS:
        raise BuildingChoiceError(f"--building {text}: unknown building model '{kind}' (rc, energyplus[:IDF], "
                                  "fmu:PATH)")
    if kind == "rc" and path:
        raise BuildingChoiceError(f"--building {text}: the 4R3C takes no file (its parameters are the plant "
                                  "file's section building)")
    if kind == "fmu" and not path:
        raise BuildingChoiceError(f"--building {text}: give the FMU as fmu:PATH.fmu")
    if map_path is not None and kind != "fmu":
        raise BuildingChoiceError(f"--building-map is for --building fmu:PATH, not {text}")
    if epw is not None and kind != "energyplus":
        raise BuildingChoiceError(f"--epw is for --building energyplus, not {text}")
    p = Path(path) if path else None
    m = Path(map_path) if map_path is not None else None
    if kind == "fmu" and m is None:
        from comems4build_ros.core.models.building_fmu import default_map_path

        m = default_map_path(p)
    return BuildingChoice(kind, p, m, Path(epw) if epw is not None else None)


def check_building(choice: BuildingChoice) -> None:
    """Check the choice's files before a run.

    Parameters
    ----------
    choice : BuildingChoice
        The parsed ``--building`` value.

    Raises
    ------
    BuildingChoiceError
        If the IDF, EPW, FMU or its map cannot serve a run, naming the file and field.
    """
    if choice.kind == "energyplus":
        from comems4build_ros.core.models.building_energyplus import IDFError, check_idf
        from comems4build_ros.core.models.epw import EPWError, epw_hours

        try:
            check_idf(choice.path) if choice.path else None
            if choice.epw is not None:
                epw_hours(choice.epw)
        except (IDFError, EPWError) as exc:
            raise BuildingChoiceError(str(exc)) from None
    elif choice.kind == "fmu":
        from comems4build_ros.core.models.building_fmu import FMUError, check_fmu, load_map

        try:
            check_fmu(choice.path, load_map(choice.map_path))
        except FMUError as exc:
            raise BuildingChoiceError(str(exc)) from None


def check_covers(choice: BuildingChoice, weather: Weather, site: object, n_steps: int) -> None:
    """Refuse, for ``energyplus`` with an EPW given, one that does not cover the run.

    Parameters
    ----------
    choice : BuildingChoice
        The parsed ``--building`` value (nothing to check without ``epw``).
    weather : Weather
        The run's weather (its first step and time zone).
    site : SiteParams
        The site (its time zone).
    n_steps : int
        Hours of the run.

    Raises
    ------
    BuildingChoiceError
        Naming the file and the first missing hour.
    """
    if choice.kind != "energyplus" or choice.epw is None:
        return
    from comems4build_ros.core.models.epw import EPWError, check_epw_covers, standard_offset_h, standard_times

    first = standard_times(weather.time[:1], standard_offset_h(site, weather.time))[0]
    try:
        check_epw_covers(choice.epw, first, n_steps)
    except EPWError as exc:
        raise BuildingChoiceError(str(exc)) from None


def make_building(choice: BuildingChoice | str | None, params: PlantParams, weather: Weather | None = None,
                  n_steps: int = 0, workdir: str | Path | None = None) -> BuildingModel:
    """Build the building model of ``choice`` for a run of ``n_steps`` steps over ``weather``.

    Parameters
    ----------
    choice : BuildingChoice, str or None
        The choice or the option's text (None: ``rc``).
    params : PlantParams
        Plant parameters (the 4R3C's, the step [h], the site, T_air,init [degC]).
    weather : Weather, optional
        The run's weather (``energyplus`` only: the EPW is written from it).
    n_steps : int
        Steps of the run (``energyplus`` only: its run period).
    workdir : str or Path, optional
        EnergyPlus's output folder (default: a temporary one, removed at ``close``).

    Returns
    -------
    BuildingModel
        :class:`~comems4build_ros.core.models.building.RCBuilding`, an FMU or an EnergyPlus model.

    Raises
    ------
    BuildingChoiceError
        If EnergyPlus is asked for with a step other than 1 h or without the run's weather.
    """
    if not isinstance(choice, BuildingChoice):
        choice = parse_building(choice)
    dt_h = float(params.simulation.time_step_h)
    if choice.kind == "rc":
        return RCBuilding(params.building, dt_h)
    if choice.kind == "fmu":  # FMUBuilding checks the FMU against its map (the command checked them before too)
        from comems4build_ros.core.models.building_fmu import FMUBuilding, load_map

        return FMUBuilding(choice.path, load_map(choice.map_path), dt_h)
    from comems4build_ros.core.models.building_energyplus import EnergyPlusBuilding

    if dt_h != 1.0:
        raise BuildingChoiceError(f"--building energyplus: the plant's step must be 1 h, got {dt_h} h")
    if weather is None or n_steps <= 0:
        raise BuildingChoiceError("--building energyplus needs the run's weather and length")
    check_covers(choice, weather, params.site, n_steps)
    return EnergyPlusBuilding(choice.path, weather, params.site, n_steps, params.simulation.t_air_init_c,
                              workdir=workdir, epw=choice.epw)
