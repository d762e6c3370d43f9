"""Shared option types and checks of the command line.

Every numeric option of every subcommand is parsed by one of the types below, so that a
value outside its allowed range (``--weeks 0``, ``--weeks inf``, ``--jobs -1``) ends in
argparse's usage error (exit code 2) naming the option, the value and the allowed range,
before any work starts. The ranges are stated in the option's help text by
:func:`range_text`.

Output paths are checked before a run starts with :func:`comems4build_ros.files.outputs.check_out_dir`
and :func:`~comems4build_ros.files.outputs.check_out_file`.
"""

from __future__ import annotations

import argparse
import math
import re
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from comems4build_ros.app.cli import UsageError
from comems4build_ros.files.errors import InputError

__all__ = ["UsageError"]  # re-exported for the commands

#: Largest ROS 2 domain id (the DDS port formula of ROS 2 allows 0..232).
ROS_DOMAIN_ID_MAX = 232
#: Largest seed of numpy's generators accepted here (unsigned 32 bit, like the ROS parameter).
SEED_MAX = 2**32 - 1


def range_text(lo: float | None = None, hi: float | None = None, lo_open: bool = False, hi_open: bool = False) -> str:
    """Human text of an interval: ``> 0``, ``>= 1``, ``in [0, 1]``, ``in (0, 1]``."""
    def num(x: float) -> str:
        return str(int(x)) if float(x).is_integer() else f"{x:g}"

    if lo is not None and hi is not None:
        return f"in {'(' if lo_open else '['}{num(lo)}, {num(hi)}{')' if hi_open else ']'}"
    if lo is not None:
        return f"{'>' if lo_open else '>='} {num(lo)}"
    if hi is not None:
        return f"{'<' if hi_open else '<='} {num(hi)}"
    return "finite"


def _number(kind: type, lo: float | None, hi: float | None, lo_open: bool, hi_open: bool,
            zero: bool = False) -> Callable[[str], float]:
    what = "an integer" if kind is int else "a finite number"
    allowed = ("0 (off) or " if zero else "") + range_text(lo, hi, lo_open, hi_open)

    def parse(text: str) -> float:
        from comems4build_ros.files.inputs import parse_decimal, parse_integer

        try:  # a plain decimal, as every number the project reads (no 1_000, other scripts' digits, nan words)
            value = parse_integer(text) if kind is int else parse_decimal(text)
        except InputError:
            raise argparse.ArgumentTypeError(f"'{text}' is not {what} (allowed: {allowed})") from None
        if kind is float and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"'{text}' is not {what} (allowed: {allowed})")
        low_bad = lo is not None and (value <= lo if lo_open else value < lo)
        high_bad = hi is not None and (value >= hi if hi_open else value > hi)
        if (low_bad or high_bad) and not (zero and value == 0):
            raise argparse.ArgumentTypeError(f"{text} is outside the allowed range: {what} {allowed}")
        return value

    parse.__name__ = "integer" if kind is int else "number"  # argparse names the type in its messages
    return parse


def real(lo: float | None = None, hi: float | None = None, lo_open: bool = False,
         hi_open: bool = False, zero: bool = False) -> Callable[[str], float]:
    """argparse type: a finite float within the interval (``lo_open``: ``lo`` itself excluded; ``zero``: or 0,
    meaning off, where the smallest real value lies above it)."""
    return _number(float, lo, hi, lo_open, hi_open, zero)


def integer(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """argparse type: an integer within ``[lo, hi]``."""
    return _number(int, lo, hi, False, False)  # type: ignore[return-value]


#: Longest run [h]: 30 years, the service life of a house's PV, battery and heat pump (20..30 years in
#: their datasheets' warranties); a longer run stands for no installation, and its end date would soon lie
#: beyond what a calendar type holds (pandas: 2262).
MAX_RUN_HOURS = 30 * 8766
#: Shortest run [h]: one step of the scenario's hourly rows.
MIN_RUN_HOURS = 1
#: Run length in weeks: one hour .. 30 years (whole hours are checked with the scenario).
WEEKS = real(MIN_RUN_HOURS / 168, MAX_RUN_HOURS / 168)
#: Run length in hours: an integer in 1 .. 30 years.
HOURS = integer(MIN_RUN_HOURS, MAX_RUN_HOURS)
#: Run length in whole weeks (the benchmarks' in-process runs): 1 .. 30 years.
WHOLE_WEEKS = integer(1, MAX_RUN_HOURS // 168)
#: An optional run length in weeks: 0 (off) or one hour .. 30 years.
WEEKS_OR_OFF = real(MIN_RUN_HOURS / 168, MAX_RUN_HOURS / 168, zero=True)
#: A count of runs, houses, steps or repeats: an integer >= 1.
COUNT = integer(1)
#: Shortest time limit or timeout [s]: 10 ms, below the time any node needs to answer one message.
MIN_SECONDS = 0.01
#: Longest time limit or timeout [s]: a year (any run or study of this package ends far sooner).
MAX_SECONDS = 365 * 24 * 3600.0
#: A duration in seconds: 10 ms .. a year.
SECONDS = real(MIN_SECONDS, MAX_SECONDS)
#: A seed: 0 .. 2**32-1.
SEED = integer(0, SEED_MAX)
#: A ROS 2 domain id: 0 .. 232.
DOMAIN_ID = integer(0, ROS_DOMAIN_ID_MAX)
#: A fraction: finite, in [0, 1].
FRACTION = real(0, 1)
#: Most houses of one ROS launch: a plan of 1000 houses is built in about 2 s (100000 did not
#: finish in 5 min); the runs measured go up to 16 (``bench ros``).
MAX_HOUSES = 1000
#: A number of houses of a launch: 1 .. MAX_HOUSES.
HOUSES = integer(1, MAX_HOUSES)


def parse_values(text: str, option: str, integer: bool) -> list[float]:
    """``"6,9.6,12"`` of a size option -> its values (positive; integers >= 0 for ``integer``), each once."""
    from comems4build_ros.files.inputs import parse_decimal

    values: list[float] = []
    for item in text.split(","):
        item = item.strip()
        try:
            v = parse_decimal(item)
        except InputError:
            try:  # 'nan', 'inf', 'infinity' as Python reads them: numbers, but not finite ones
                v = float(item)
            except ValueError:
                raise UsageError(f"{option} '{text}': '{item}' is not a number") from None
        if not math.isfinite(v):
            raise UsageError(f"{option} '{text}': '{item}' is not a finite number")
        if integer:
            if v != int(v) or v < 0:
                raise UsageError(f"{option} '{text}': '{item}' is not an integer >= 0")
            v = int(v)
        elif v <= 0:
            raise UsageError(f"{option} '{text}': '{item}' must be > 0")
        if v in values:
            raise UsageError(f"{option} '{text}': {item} is given twice")
        values.append(v)
    return values


def add_scenario_options(parser: argparse.ArgumentParser, hours: bool = True, seed: bool = True,
                         extend: bool = True) -> None:
    """``--scenario``, ``--start``, ``--weeks`` / ``--hours``, ``--seed`` and ``--extend`` of a run."""
    parser.add_argument("--scenario", metavar="default|year|synthetic|FILE.csv", default="default",
                        help="'default' (the paper's winter, measured data), 'year' (the year around it from "
                             "2022-03-01 with an electrolyser and cooling, config/year.yaml), 'synthetic' (the "
                             "seeded generator) or a scenario CSV file")
    parser.add_argument("--start", metavar="ISO", default=None,
                        help="first step of the window (ISO date/time; naive = site time)")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--weeks", type=WEEKS, default=None, metavar="N",
                       help="run length in weeks, one hour .. 30 years (fractions giving whole hours allowed; "
                            "default: the scenario's whole weeks)")
    if hours:
        group.add_argument("--hours", type=HOURS, default=None, metavar="H",
                           help=f"run length in hours, integer in 1 .. {MAX_RUN_HOURS} (30 years; short tries; "
                                "instead of --weeks)")
    if seed:
        parser.add_argument("--seed", metavar="N", type=SEED, default=None,
                            help="seed of the generated scenario data (default scenario, --extend synthetic; "
                                 "default: config/scenario.yaml)")
    if extend:
        parser.add_argument("--extend", choices=("synthetic",), default=None,
                            help="a run longer than the scenario's data is refused unless this is given: "
                                 "'synthetic' appends generated data after the data's end (summary.json "
                                 "says so under scenario_extended)")


def add_scenario_config(args: argparse.Namespace) -> None:
    """Put the plant file of an embedded scenario (``--scenario year``: ``config/year.yaml``)
    in front of ``args.config``, so that ``--config`` files and ``--set`` still override it."""
    from comems4build_ros.core.config import scenario_config_files

    args.config = scenario_config_files(getattr(args, "scenario", "default"), args.config)


def check_config_files(paths: Sequence[str], option: str = "--config") -> None:
    """Each ``--config`` file exists and is a regular file (a directory or device is named as such)."""
    from comems4build_ros.core.config import check_input_file

    for path in paths:
        check_input_file(path, option)


def load_params(config: Sequence[str], overrides: Mapping[str, Any] | None = None) -> Any:
    """Plant parameters of ``--config`` files and ``--set`` overrides, the files checked first."""
    from comems4build_ros.core.config import load_plant_params

    check_config_files(config)
    return load_plant_params(config, overrides)


def ems_help(many: bool = False) -> str:
    """Help text of an ``--ems`` option: the EMS of ``config/ems.yaml``."""
    from comems4build_ros.core.ems import ems_names as table_names

    names = ", ".join(table_names())
    return f"comma-separated EMS names, of {names}" if many else f"EMS name: {names}"


def table_names(text: str, option: str, what: str, check: Callable[[str], Any], unknown: type[Exception]) -> list[str]:
    """A comma-separated option of names of a table (``--ems``, ``--coordinator``): each once, each known, at least one.

    ``check(name)`` raises ``unknown`` for a name the table does not hold; every refusal is a
    usage error naming ``option``.
    """
    names = [e.strip() for e in text.split(",") if e.strip()]
    if not names:
        raise UsageError(f"{option} '{text}': no {what} given")
    for i, name in enumerate(names):
        if name in names[:i]:
            raise UsageError(f"{option} {text}: '{name}' given twice (its runs would overwrite each other)")
        try:
            check(name)
        except unknown as exc:
            raise UsageError(f"{option} {name}: {exc}") from None
    return names


def ems_names(text: str) -> list[str]:
    """``--ems rbc,fuzzy,mpc`` of ``compare`` and ``sweep``: registered names, each once, at least one."""
    from comems4build_ros.core.ems import UnknownEMSError, controller_class

    return table_names(text, "--ems", "EMS", controller_class, UnknownEMSError)


def ems_controller(name: str, params: Any, items: Sequence[str]) -> Any:
    """The EMS ``name`` built with its ``--ems-option`` items by the constructor its node or loop uses.

    So every option is checked by the controller's own rules (unknown keys, ranges, an
    inverted hysteresis) before anything runs or starts; an unknown EMS is named as
    ``--ems``, a bad option (:class:`~comems4build_ros.core.config.ConfigError`) by its key.
    """
    from comems4build_ros.core.config import parse_assignments
    from comems4build_ros.core.ems import UnknownEMSError, make_controller
    from comems4build_ros.core.ems.base import check_mpc_horizon

    options = parse_assignments(items, "--ems-option")
    try:
        controller = make_controller(name, params, options)
    except UnknownEMSError as exc:
        raise UsageError(f"--ems {name}: {exc}") from None
    if controller.info_level == "mpc":  # the horizon the loop's observation carries
        check_mpc_horizon(params.simulation.horizon_h, params.simulation.time_step_h)
    return controller


def check_start(start: str | None, params: Any) -> None:
    """``--start``: ISO 8601, naive = site time, not in a DST gap nor ambiguous (the message names ``--start``)."""
    from comems4build_ros.core.scenario.csvio import local_time

    if start is not None:
        local_time(start, params.site.timezone, "--start")


def scenario_of(args: argparse.Namespace, params: Any) -> Any:
    """The run's scenario from the options of :func:`add_scenario_options`."""
    from comems4build_ros.core.scenario import resolve_scenario

    check_start(args.start, params)
    return resolve_scenario(args.scenario, params, start=args.start, weeks=args.weeks,
                            hours=getattr(args, "hours", None), seed=getattr(args, "seed", None),
                            extend=getattr(args, "extend", None))


#: URL schemes of a Dask scheduler address (TLS when the cluster is configured for it).
SCHEDULER_SCHEMES = ("tcp", "tls")


def scheduler_address(text: str) -> str:
    """argparse type of ``--scheduler``: ``tcp://HOST:PORT`` (or ``tls://``), port 1..65535."""
    from urllib.parse import urlsplit

    form = "tcp://HOST:PORT (or tls://HOST:PORT), e.g. tcp://10.0.0.5:8786"
    if re.fullmatch(r"[a-z]+://(\[[0-9A-Fa-f:.]+\]|[^\s/:@\[\]?#]+):[0-9]{1,5}/?", text) is None:
        raise argparse.ArgumentTypeError(f"'{text}' is not {form}")
    url = urlsplit(text)
    port = url.port
    if url.scheme not in SCHEDULER_SCHEMES or not url.hostname or port is None or url.path not in ("", "/") \
            or url.query or url.username or url.password:
        raise argparse.ArgumentTypeError(f"'{text}' is not {form}")
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"'{text}': port {port} is outside 1..65535")
    return f"{url.scheme}://{url.netloc}"


def add_pool_options(parser: argparse.ArgumentParser, jobs_default: str = "CPU count") -> None:
    """``--jobs``, ``--scheduler``, ``--resume``: where a study's runs execute and whether it resumes."""
    parser.add_argument("--jobs", metavar="N", type=COUNT, default=None,
                        help=f"parallel runs in local worker processes, integer >= 1 (default: {jobs_default}; "
                             "at most the CPU count)")
    parser.add_argument("--scheduler", metavar="tcp://HOST:PORT", type=scheduler_address, default=None,
                        help="run on the workers of this Dask scheduler instead of local processes (docs/cluster.md); "
                             "every worker must run the same code, parameter files and library versions")
    parser.add_argument("--resume", action="store_true",
                        help="take the runs an interrupted study of the same --out finished (OUT/.runstore) instead "
                             "of running them again; a stored run of another specification is refused")


def study_pool(args: argparse.Namespace, out: str | Any, jobs: int | None = None) -> Any:
    """The :class:`~comems4build_ros.study.pool.StudyPool` of ``--jobs``/``--scheduler``/``--resume``.

    Its store is ``out/.runstore``; ``jobs`` replaces ``--jobs`` when given (a command's own
    default). Enter it before any run: it connects and checks the cluster, and refuses a
    store of an unfinished study without ``--resume``.
    """
    from comems4build_ros.study.pool import DaskBackend, LocalBackend, StudyPool
    from comems4build_ros.study.store import RunStore

    if args.scheduler and args.jobs is not None:
        raise UsageError("--jobs and --scheduler exclude each other (with --scheduler the cluster's workers run "
                         "the runs, as many at once as they have threads)")
    if args.scheduler:  # a Dask scheduler there, proven by its handshake, before any work
        from comems4build_ros.study.cluster import probe_scheduler

        probe_scheduler(args.scheduler)
    backend = DaskBackend(args.scheduler) if args.scheduler else LocalBackend(jobs if jobs is not None else args.jobs)
    return StudyPool(backend, RunStore.of(out), resume=args.resume)


def add_forecast_option(parser: argparse.ArgumentParser) -> None:
    """``--forecast MODE``: the MPC's forecasts (:data:`comems4build_ros.core.types.FORECAST_MODES`)."""
    from comems4build_ros.core.types import FORECAST_MODES

    parser.add_argument("--forecast", choices=FORECAST_MODES, default=None,
                        help="forecasts given to the MPC: perfect (the paper's), imperfect or realistic (prices as "
                             "published, correlated weather errors; docs/mpc.md) (default: config/forecast.yaml, "
                             "perfect)")


def add_building_options(parser: argparse.ArgumentParser) -> None:
    """``--building MODEL``, ``--building-map FILE`` and ``--epw FILE``: the building model of a run."""
    parser.add_argument("--building", metavar="MODEL", default="rc",
                        help="the building's thermal model: 'rc' (the paper's 4R3C, default), 'energyplus' (the "
                             "shipped German single-family house in EnergyPlus) or 'energyplus:FILE.idf', or "
                             "'fmu:FILE.fmu' (an FMI 2.0 co-simulation FMU); docs/cosimulation.md")
    parser.add_argument("--building-map", metavar="FILE", default=None,
                        help="variable map of --building fmu:FILE.fmu (default: FILE.map.yaml beside the FMU)")
    parser.add_argument("--epw", metavar="FILE", default=None,
                        help="weather file for --building energyplus instead of the one written from the scenario "
                             "(must cover the run)")


def building_choice(args: argparse.Namespace) -> Any:
    """The checked :class:`~comems4build_ros.core.models.buildings.BuildingChoice` of the options.

    A bad value, a broken IDF, an FMU that does not load or a map naming a variable the FMU
    lacks is a usage error (exit 2) naming the file and the field, before anything runs.
    """
    from comems4build_ros.core.models.buildings import BuildingChoiceError, check_building, parse_building

    try:
        choice = parse_building(getattr(args, "building", "rc"), getattr(args, "building_map", None),
                                getattr(args, "epw", None))
        check_building(choice)
    except BuildingChoiceError as exc:
        raise UsageError(str(exc)) from None
    return choice


def add_study_options(parser: argparse.ArgumentParser, config_help: str = "config/plant.yaml",
                      jobs_default: str = "CPU count") -> None:
    """What every study command (compare, sweep, size) offers: ``--config``, where its runs
    execute (:func:`add_pool_options`), the building model (:func:`add_building_options`)
    and ``--no-progress``."""
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help=f"parameter file merged over {config_help} (repeatable)")
    add_pool_options(parser, jobs_default)
    add_building_options(parser)
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars (one per run)")


def study_inputs(args: argparse.Namespace) -> list[str]:
    """The checked inputs of a study command: its EMS names (returned), its scenario settings,
    building model (set as ``args.building_choice``) and parameter files; a usage error
    (exit 2) names the option before any run starts."""
    add_scenario_config(args)
    emss = ems_names(args.ems)
    args.building_choice = building_choice(args)
    check_config_files(args.config)
    return emss


def check_building_covers(choice: Any, scenario: Any, params: Any) -> None:
    """An ``--epw`` that does not cover the scenario's run is a usage error naming the file and field."""
    from comems4build_ros.core.models.buildings import BuildingChoiceError, check_covers
    from comems4build_ros.core.models.epw import Weather

    weather = Weather(scenario.time, scenario.t_amb_c, scenario.ghi_w_m2, scenario.dhi_w_m2)
    try:
        check_covers(choice, weather, params.site, scenario.n_steps)
    except BuildingChoiceError as exc:
        raise UsageError(str(exc)) from None
#: Options of the commands that name input files or directories (what an output must not overwrite).
INPUT_OPTIONS = ("config", "costs", "scenario", "topic_map", "live_config", "bag", "prices", "temperature", "solar",
                 "dhw", "load", "from_json", "from_runs", "building", "building_map", "epw", "community")


def command_inputs(args: argparse.Namespace) -> dict[str, list[str]]:
    """Every input path a command's options name (``--config``, ``--scenario FILE.csv``, a bag, ...): option -> paths.

    The one list the output layer checks an output against
    (:func:`comems4build_ros.files.outputs.check_not_input`); a ``--scenario`` that names an
    embedded scenario (``default``, ``year``, ``synthetic``) is no path. ``evaluate``'s
    positional bag is ``BAG``; ``launch``'s ``--bag`` is an output, not an input.
    ``--from-runs DIR`` reads ``DIR/runs/`` and the study's record in ``DIR``
    (``compare.json``, ``reproduce.json``, ``validation.json``), so that a report can be rebuilt beside its runs.
    """
    from pathlib import Path

    out: dict[str, list[str]] = {}
    for name in INPUT_OPTIONS:
        value = getattr(args, name, None)
        if value is None or (name == "bag" and getattr(args, "command", "") == "launch"):
            continue
        values = [str(v) for v in (value if isinstance(value, list | tuple) else [value]) if str(v)]
        if name == "scenario":
            values = [v for v in values if Path(v).is_file()]
        if name == "building":  # energyplus:FILE.idf, fmu:FILE.fmu name a file; rc and energyplus none
            values = [v.partition(":")[2] for v in values if v.partition(":")[2]]
        if name == "from_runs":
            values = [str(Path(v) / sub) for v in values
                      for sub in ("runs", "compare.json", "reproduce.json", "validation.json", "size_community.json")]
        if values:
            out["BAG" if name == "bag" else f"--{name.replace('_', '-')}"] = values
    return out


def output_dir(args: argparse.Namespace, command: str, writes: Sequence[str] = ("*",), replaces: Sequence[str] = (),
               path: Any = None, option: str = "--out", in_place: bool = False) -> Any:
    """The :class:`~comems4build_ros.files.outputs.OutputDir` of a command's ``--out``, checked against its inputs.

    Enter it before any run: it refuses an empty or ambiguous path, an output that is, lies
    inside or would replace an input, a second command on the same directory and entries in
    the way that comems4build did not write (each as a usage error, exit code 2).
    """
    from comems4build_ros.files.outputs import OutputDir

    return OutputDir(args.out if path is None else path, command, option=option, inputs=command_inputs(args),
                     writes=writes, replaces=replaces, in_place=in_place)


def output_file(args: argparse.Namespace, command: str, path: Any = None, option: str = "--out") -> Any:
    """The :class:`~comems4build_ros.files.outputs.OutputFile` of a command's one output file (``data build``)."""
    from comems4build_ros.files.outputs import OutputFile

    return OutputFile(args.out if path is None else path, command, option=option, inputs=command_inputs(args))


def bench_output(args: argparse.Namespace, command: str) -> Any:
    """The output layer for a benchmark's optional ``--out`` (in place: its runs can be watched), or no-op."""
    import contextlib

    if getattr(args, "out", None) is None:
        return contextlib.nullcontext()
    output = output_dir(args, command, in_place=True)
    output.check()
    return output
