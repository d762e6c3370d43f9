"""A building model brought as an FMI 2.0 co-simulation FMU (run with fmpy), and its variable map.

The FMU is any FMI 2.0 co-simulation unit that models the house's rooms (a house of the
Modelica Buildings library exported by a Modelica tool, or the 4R3C of ``comems4build
export-fmu``). A *variable map* (YAML) names the FMU's variables for the building-model
interface (:class:`~comems4build_ros.core.models.building.BuildingModel`)::

    inputs:                   # what the plant gives each step (FMI causality input)
      q_floor_w: Q_floor      # heat into the floor [W], negative when cooling (required)
      t_amb_c: T_amb          # ambient temperature [degC] (required)
      ghi_w_m2: q_sol         # global horizontal irradiance [W/m2] (optional)
      p_load_w: P_gains       # appliance load, released as heat [W] (optional)
    outputs:                  # what the plant reads after each step (causality output)
      t_air_c: T_air          # required
      t_wall_in_c: T_w_in     # optional (else T_air)
      t_wall_out_c: T_w_out   # optional (else T_air)
    start:                    # parameters set before initialisation (optional)
      t_air_c: T_air_start    # the air temperature the run starts from
      t_amb_c: T_amb_start
    parameters: {}            # further parameters: FMU name -> value (optional)

Every name is checked against the FMU's ``modelDescription.xml`` before the run
(:func:`check_fmu`); a missing or mistyped one is refused naming the variable, the map and
the FMU. The master steps the FMU with the plant's step (3600 s) as communication step; the
FMU integrates inside with its own solver or steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from comems4build_ros.core.models.building import Temperatures
from comems4build_ros.core.types import Exogenous
from comems4build_ros.files.errors import InputError

#: Keys of the map: section -> (key -> required).
MAP_KEYS: dict[str, dict[str, bool]] = {
    "inputs": {"q_floor_w": True, "t_amb_c": True, "ghi_w_m2": False, "p_load_w": False},
    "outputs": {"t_air_c": True, "t_wall_in_c": False, "t_wall_out_c": False},
    "start": {"t_air_c": False, "t_amb_c": False},
}
#: FMI causality each section's variables must have.
CAUSALITY = {"inputs": ("input",), "outputs": ("output",), "start": ("parameter",), "parameters": ("parameter",)}


class FMUError(InputError):
    """An FMU or variable map that cannot serve the run; the message names the file and the variable or field."""


@dataclass
class VariableMap:
    """The FMU's variable names for the interface (see the module docstring).

    Attributes
    ----------
    path : Path
        The map file.
    inputs : dict of str to str
        ``q_floor_w`` [W], ``t_amb_c`` [degC], ``ghi_w_m2`` [W/m2], ``p_load_w`` [W] -> FMU input.
    outputs : dict of str to str
        ``t_air_c`` (and ``t_wall_in_c``, ``t_wall_out_c``) [degC] -> FMU output.
    start : dict of str to str
        ``t_air_c``, ``t_amb_c`` [degC] -> FMU parameter set at initialisation.
    parameters : dict of str to float
        FMU parameter -> value, set at initialisation (units of the FMU).
    """

    path: Path
    inputs: dict[str, str]
    outputs: dict[str, str]
    start: dict[str, str] = field(default_factory=dict)
    parameters: dict[str, float] = field(default_factory=dict)


def default_map_path(fmu: str | Path) -> Path:
    """Return the map beside an FMU: ``house.fmu`` -> ``house.map.yaml``.

    Parameters
    ----------
    fmu : str or Path
        The FMU file.

    Returns
    -------
    Path
        The map's path (not checked to exist).
    """
    fmu = Path(fmu)
    return fmu.with_name(fmu.stem + ".map.yaml")


def load_map(path: str | Path) -> VariableMap:
    """Read and check the structure of a variable map (names are checked against the FMU by :func:`check_fmu`).

    Parameters
    ----------
    path : str or Path
        The map (YAML with ``inputs``, ``outputs``, ``start``, ``parameters``).

    Returns
    -------
    VariableMap
        The map's sections.

    Raises
    ------
    FMUError
        If the file is missing, not YAML, or a section or field is unknown, missing or of the
        wrong type, naming the file and field.
    """
    import yaml

    path = Path(path)
    if not path.is_file():
        raise FMUError(f"{path}: variable map not found (give --building-map FILE, or put NAME.map.yaml beside "
                       "the FMU)")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except yaml.YAMLError as exc:
        raise FMUError(f"{path}: not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise FMUError(f"{path}: the variable map must be a mapping with inputs, outputs, start, parameters")
    unknown = set(data) - {*MAP_KEYS, "parameters", "description"}
    if unknown:
        raise FMUError(f"{path}: field {sorted(unknown)[0]}: unknown section (allowed: inputs, outputs, start, "
                       "parameters)")
    sections: dict[str, dict[str, str]] = {}
    for section, keys in MAP_KEYS.items():
        raw = data.get(section) or {}
        if not isinstance(raw, dict):
            raise FMUError(f"{path}: field {section}: must be a mapping KEY: FMU_VARIABLE")
        for key in raw:
            if key not in keys:
                raise FMUError(f"{path}: field {section}.{key}: unknown (allowed: {', '.join(keys)})")
        for key, required in keys.items():
            if required and not raw.get(key):
                raise FMUError(f"{path}: field {section}.{key}: missing (the FMU variable that gives it)")
            if key in raw and not isinstance(raw[key], str):
                raise FMUError(f"{path}: field {section}.{key}: must be an FMU variable name, got {raw[key]!r}")
        sections[section] = {k: v for k, v in raw.items() if v}
    params = data.get("parameters") or {}
    if not isinstance(params, dict):
        raise FMUError(f"{path}: field parameters: must be a mapping FMU_VARIABLE: VALUE")
    for key, value in params.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise FMUError(f"{path}: field parameters.{key}: must be a number, got {value!r}")
    return VariableMap(path, sections["inputs"], sections["outputs"], sections["start"],
                       {str(k): float(v) for k, v in params.items()})


def check_fmu(fmu: str | Path, vmap: VariableMap) -> Any:
    """Read the FMU's model description and check it against the map.

    Parameters
    ----------
    fmu : str or Path
        The FMU file.
    vmap : VariableMap
        Its variable map.

    Returns
    -------
    fmpy.model_description.ModelDescription
        The FMU's model description.

    Raises
    ------
    FMUError
        The FMU is missing or does not load, is not FMI 2.0 co-simulation, or lacks a
        variable the map names (or has it with another causality or a non-Real type).
    """
    from fmpy import read_model_description

    fmu = Path(fmu)
    if not fmu.is_file():
        raise FMUError(f"{fmu}: FMU file not found")
    try:
        md = read_model_description(str(fmu), validate=True)
    except Exception as exc:  # fmpy raises plain Exceptions for a broken archive or XML
        raise FMUError(f"{fmu}: the FMU does not load: {type(exc).__name__}: {exc}") from None
    if not str(md.fmiVersion).startswith("2."):
        raise FMUError(f"{fmu}: field fmiVersion: {md.fmiVersion}, FMI 2.0 required")
    if md.coSimulation is None:
        raise FMUError(f"{fmu}: field CoSimulation: the FMU is not a co-simulation FMU")
    variables = {v.name: v for v in md.modelVariables}
    for section in ("inputs", "outputs", "start", "parameters"):
        names = getattr(vmap, section)
        for key, name in (names.items() if section != "parameters" else ((k, k) for k in names)):
            v = variables.get(name)
            if v is None:
                raise FMUError(f"{vmap.path}: field {section}.{key}: variable '{name}' is not in the FMU {fmu}")
            if v.causality not in CAUSALITY[section]:
                raise FMUError(f"{vmap.path}: field {section}.{key}: variable '{name}' of the FMU {fmu} has "
                               f"causality {v.causality}, {'/'.join(CAUSALITY[section])} required")
            if v.type != "Real":
                raise FMUError(f"{vmap.path}: field {section}.{key}: variable '{name}' of the FMU {fmu} is "
                               f"{v.type}, Real required")
    return md


class FMUBuilding:
    """A building model in an FMI 2.0 co-simulation FMU, stepped by fmpy (see the module docstring).

    Parameters
    ----------
    fmu : str or Path
        The FMU file (FMI 2.0 co-simulation, the FMI standard of the Modelica Association).
    vmap : VariableMap
        Its variable map (:func:`load_map`).
    dt_h : float
        The plant's step, the communication step [h].

    Raises
    ------
    FMUError
        If the FMU does not fit the map (:func:`check_fmu`).
    """

    name = "fmu"

    def __init__(self, fmu: str | Path, vmap: VariableMap, dt_h: float) -> None:
        self.fmu = Path(fmu)
        self.map = vmap
        self.md = check_fmu(self.fmu, vmap)
        self.dt_s = float(dt_h) * 3600.0
        self._vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self._slave: Any = None
        self._unzipdir: str | None = None
        self._time = 0.0
        m = vmap
        self._in_keys = list(m.inputs)
        self._in_refs = [self._vr[m.inputs[k]] for k in self._in_keys]
        out = m.outputs
        self._out_refs = [self._vr[out["t_air_c"]], self._vr[out.get("t_wall_in_c", out["t_air_c"])],
                          self._vr[out.get("t_wall_out_c", out["t_air_c"])]]

    def initial_temperatures(self, t_air_c: float, t_amb_c: float) -> Temperatures:
        """Instantiate and initialise the FMU (start values from the map) and read its outputs.

        Parameters
        ----------
        t_air_c : float
            Indoor air temperature at the start [degC].
        t_amb_c : float
            Ambient temperature before the run [degC].

        Returns
        -------
        Temperatures
            The FMU's (T_air, T_w,in, T_w,out) [degC] (T_air where it gives no wall node).
        """
        from fmpy import extract
        from fmpy.fmi2 import FMU2Slave

        self._unzipdir = extract(str(self.fmu))
        cs = self.md.coSimulation
        slave = FMU2Slave(guid=self.md.guid, unzipDirectory=self._unzipdir, modelIdentifier=cs.modelIdentifier,
                          instanceName="building")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        values = {"t_air_c": float(t_air_c), "t_amb_c": float(t_amb_c)}
        refs = [self._vr[name] for name in self.map.start.values()]
        if refs:
            slave.setReal(refs, [values[k] for k in self.map.start])
        if self.map.parameters:
            slave.setReal([self._vr[k] for k in self.map.parameters], list(self.map.parameters.values()))
        slave.exitInitializationMode()
        self._slave = slave
        self._time = 0.0
        a, b, c = slave.getReal(self._out_refs)
        return (float(a), float(b), float(c))

    def step(self, temps: Temperatures, q_floor_w: float, exo: Exogenous) -> Temperatures:
        """Advance the FMU by one communication step of the plant's length with the step's inputs.

        Parameters
        ----------
        temps : Temperatures
            Ignored: the FMU keeps its own state [degC].
        q_floor_w : float
            Heat into the floor [W] (negative: cooling).
        exo : Exogenous
            T_amb [degC], GHI [W/m2] and the appliance load [W] of the step.

        Returns
        -------
        Temperatures
            The FMU's outputs at the step's end [degC].
        """
        values = {"q_floor_w": q_floor_w, "t_amb_c": exo.t_amb_c, "ghi_w_m2": exo.ghi_w_m2, "p_load_w": exo.p_load_w}
        s = self._slave
        s.setReal(self._in_refs, [float(values[k]) for k in self._in_keys])
        s.doStep(currentCommunicationPoint=self._time, communicationStepSize=self.dt_s)
        self._time += self.dt_s
        a, b, c = s.getReal(self._out_refs)
        return (float(a), float(b), float(c))

    def close(self) -> None:
        """Terminate and free the FMU instance and remove its extracted files."""
        import shutil

        if self._slave is not None:
            try:
                self._slave.terminate()
            finally:
                self._slave.freeInstance()
                self._slave = None
        if self._unzipdir:
            shutil.rmtree(self._unzipdir, ignore_errors=True)
            self._unzipdir = None


#: The variable map of the 4R3C FMU that :func:`export_rc_fmu` writes beside it.
RC_MAP = {
    "description": "4R3C building of the ComEMS4Build paper (comems4build export-fmu)",
    "inputs": {"q_floor_w": "Q_floor", "t_amb_c": "T_amb", "ghi_w_m2": "q_sol", "p_load_w": "P_gains"},
    "outputs": {"t_air_c": "T_air", "t_wall_in_c": "T_w_in", "t_wall_out_c": "T_w_out"},
    "start": {"t_air_c": "T_air_start", "t_amb_c": "T_amb_start"},
}


def export_rc_fmu(building: Any, out: str | Path, t_air_init_c: float) -> tuple[Path, Path]:
    """Export the 4R3C model with the parameters ``building`` as an FMI 2.0 co-simulation FMU (pythonfmu).

    Parameters
    ----------
    building : BuildingParams
        The 4R3C's parameters (:mod:`~comems4build_ros.core.models.building`).
    out : str or Path
        The FMU file to write (``.fmu``).
    t_air_init_c : float
        Start value of ``T_air_start`` [degC].

    Returns
    -------
    fmu : Path
        The FMU written.
    map : Path
        Its variable map ``NAME.map.yaml`` beside it.

    Raises
    ------
    FMUError
        If ``out`` does not end in ``.fmu``.
    """
    import json
    import shutil
    import tempfile

    import yaml
    from pythonfmu.builder import FmuBuilder

    from comems4build_ros.core.models import fmu_rc_slave

    out = Path(out)
    if out.suffix != ".fmu":
        raise FMUError(f"{out}: the FMU file name must end in .fmu")
    values = {name: float(getattr(building, name)) for name in fmu_rc_slave.PARAMETERS}
    values["t_air_init_c"] = float(t_air_init_c)
    values["t_amb_init_c"] = float(building.t_amb_init_c)
    with tempfile.TemporaryDirectory(prefix="c4b_fmu_") as tmp:
        script = Path(tmp) / "rc_building.py"
        shutil.copy2(fmu_rc_slave.__file__, script)
        params = Path(tmp) / "rc_parameters.json"
        params.write_text(json.dumps(values, indent=1), encoding="utf-8")
        out.parent.mkdir(parents=True, exist_ok=True)
        built = FmuBuilder.build_FMU(script, dest=out, project_files=[params])
    if Path(built) != out:
        shutil.move(str(built), out)
    vmap = default_map_path(out)
    vmap.write_text(yaml.safe_dump(RC_MAP, sort_keys=False), encoding="utf-8")
    return out, vmap
