"""``comems4build data``: build scenario CSVs from real sources.

- ``data fetch-prices --start DATE --end DATE --out prices.json`` downloads aWATTar
  day-ahead prices (internet access needed; urllib only).
- ``data build --prices X.json --temperature Y.txt --solar Z.txt [--dhw D.txt] [--load L.csv]
  --out scenario.csv`` combines the sources into a scenario CSV (hourly, local time with UTC
  offset); DHW and load come from the default generator when not given, which it says.
- ``data tariffs [--update-doc FILE]`` prints the tariff of each validation winter
  (``config/tariffs.yaml``): its mean buy price beside the published household averages, its
  feed-in rate, the components of every year and their sources; with ``--update-doc`` it
  rewrites that section of a Markdown file (``docs/validation.md``).
"""

from __future__ import annotations

import argparse

from comems4build_ros.app.commands.options import SEED, integer


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Subcommands ``fetch-prices`` and ``build``."""
    sub = parser.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    fetch = sub.add_parser("fetch-prices", help="download aWATTar day-ahead prices as JSON (needs internet)")
    fetch.add_argument("--start", metavar="ISO", required=True,
                       help="first hour, ISO date/time (naive = site local time)")
    fetch.add_argument("--end", metavar="ISO", required=True, help="end (exclusive), ISO date/time")
    fetch.add_argument("--out", metavar="FILE.json", required=True, help="JSON file to write")
    fetch.add_argument("--config", metavar="FILE", action="append", default=[],
                       help="extra plant parameter file (site time zone)")

    build = sub.add_parser("build", help="combine price, weather, DHW and load sources into a scenario CSV")
    build.add_argument("--prices", metavar="FILE.json", required=True, help="aWATTar marketdata JSON")
    build.add_argument("--temperature", metavar="FILE", required=True,
                       help="DWD air temperature, 10-minute (TT_10) or hourly (TT_TU)")
    build.add_argument("--solar", metavar="FILE", required=True,
                       help="DWD 10-minute solar radiation (GS_10, DS_10 in J/cm2)")
    build.add_argument("--dhw", metavar="FILE", help="DHWCalc output (l/h per step, one year); default: generator")
    build.add_argument("--dhw-year", metavar="YEAR", type=integer(1900, 2200),
                       help="calendar year of the DHWCalc file, 1900 .. 2200 (default: first year built)")
    build.add_argument("--load", metavar="FILE.csv",
                       help="household load CSV (time + power column); default: generator")
    build.add_argument("--load-column", metavar="NAME", help="power column of the load CSV")
    build.add_argument("--load-unit", choices=("W", "kW"), help="unit of the power column (default: from its name)")
    build.add_argument("--start", metavar="ISO",
                       help="first hour (ISO; naive = site local time); default: first common hour")
    build.add_argument("--end", metavar="ISO", help="end, exclusive (ISO); default: last common hour + 1 h")
    build.add_argument("--seed", metavar="N", type=SEED,
                       help="seed of the generator for DHW/load not given (0 .. 2^32-1)")
    build.add_argument("--config", metavar="FILE", action="append", default=[],
                       help="extra plant parameter file (site, holidays)")
    build.add_argument("--out", metavar="FILE.csv", required=True, help="scenario CSV to write")

    tariffs = sub.add_parser("tariffs", help="the tariff of each validation winter (config/tariffs.yaml): mean buy "
                                             "price beside the published household averages, feed-in rate, "
                                             "components and sources")
    tariffs.add_argument("--update-doc", metavar="FILE.md",
                         help="rewrite the section between the tariffs markers of FILE.md (docs/validation.md)")


def run(args: argparse.Namespace) -> int:
    """Run ``fetch-prices``, ``build`` or ``tariffs``."""
    from comems4build_ros.app.commands.options import UsageError, load_params, output_file

    if args.data_command == "tariffs":
        return _tariffs(args)
    from comems4build_ros.core.config import check_input_file
    from comems4build_ros.core.scenario import loaders

    params = load_params(args.config)
    tz = params.site.timezone
    for option in ("prices", "temperature", "solar", "dhw", "load"):  # the inputs first, then the output
        path = getattr(args, option, None)
        if path is not None:
            check_input_file(path, f"--{option}")
    output = output_file(args, f"data {args.data_command}")
    output.check()

    # --start / --end: ISO 8601, naive = site time (no DST gap, no ambiguous hour), checked before any file is read
    start, end = (loaders.local_time(text, tz, option) if text else None
                  for text, option in ((args.start, "--start"), (args.end, "--end")))
    if start is not None and end is not None and end <= start:
        raise UsageError("--end must be after --start")

    if args.data_command == "fetch-prices":
        import urllib.error

        try:
            text = loaders.fetch_awattar(start, end)
        except (urllib.error.URLError, TimeoutError, OSError) as exc:
            print(f"comems4build data fetch-prices: download failed: {exc}")
            return 1
        with output:  # checked as any prices file before it is put in place
            output.file.write_text(text, encoding="utf-8")
            series = loaders.read_awattar_json(output.file)
        print(f"wrote {output.target}: {len(series)} hourly prices {series.index[0]} .. {series.index[-1]}")
        return 0

    prices = (args.prices, loaders.read_awattar_json(args.prices))
    temperature = (args.temperature, loaders.read_dwd_temperature(args.temperature))
    solar = (args.solar, loaders.read_dwd_solar(args.solar))
    dhw = None
    if args.dhw:
        year = args.dhw_year or (start.year if start is not None else prices[1].index[0].tz_convert(tz).year)
        dhw = (args.dhw, loaders.read_dhwcalc(args.dhw, year, tz))
    load = (args.load, loaders.read_load_csv(args.load, args.load_column, args.load_unit)) if args.load else None
    frame, provenance = loaders.build_scenario_frame(
        params, prices, temperature, solar, dhw=dhw, load=load, start=args.start, end=args.end, seed=args.seed
    )
    with output:
        loaders.write_frame_csv(frame, output.file, tz)
    out = output.target
    first, last = frame.index[0].tz_convert(tz), frame.index[-1].tz_convert(tz)
    print(f"wrote {out}: {len(frame)} hours {first.isoformat()} .. {last.isoformat()}")
    for col, source in provenance.items():
        print(f"  {col:18s} <- {source}")
    return 0


def _tariffs(args: argparse.Namespace) -> int:
    """Print the tariff section (:mod:`comems4build_ros.report.tariffs`); rewrite it in ``--update-doc``."""
    from comems4build_ros.core.config import load_plant_params
    from comems4build_ros.core.scenario.tariff import load_tariffs
    from comems4build_ros.core.scenario.validation import winter_prices
    from comems4build_ros.report.reproduce_doc import replace_doc_section
    from comems4build_ros.report.tariffs import DOC_BEGIN, DOC_END, tariff_section

    if args.update_doc:  # the document's markers before any work
        from comems4build_ros.files.inputs import check_markers

        check_markers(args.update_doc, DOC_BEGIN, DOC_END, "--update-doc")
    section = tariff_section(winter_prices(load_plant_params()), load_tariffs())
    print(section)
    if args.update_doc:
        replace_doc_section(args.update_doc, {}, None, (DOC_BEGIN, DOC_END), "", lambda _report, _fig: section)
        print(f"updated {args.update_doc}")
    return 0
