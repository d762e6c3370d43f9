"""The tariff of each validation winter as Markdown (``comems4build data tariffs``, ``docs/validation.md``).

Three parts: each winter's mean buy price under its tariff beside the published household
averages of its two calendar years (BDEW, Bundesnetzagentur) and the feed-in rate, with the
hours the tariff prices below zero or below the feed-in rate
(:func:`~comems4build_ros.core.scenario.validation.winter_prices`); the components of every
year of ``config/tariffs.yaml``; and the sources they name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from comems4build_ros.core.scenario.tariff import LABELS, NET_COMPONENTS, Sourced, Tables, non_energy_gross
from comems4build_ros.core.scenario.validation import WinterPrices

#: Markers of the generated section in a Markdown document.
DOC_BEGIN = "<!-- tariffs:begin -->"
DOC_END = "<!-- tariffs:end -->"
#: ct per EUR.
CT_PER_EUR = 100.0
#: Month of the middle of a year's first half (the table shows the components of January..June).
JANUARY = 1


def _eur(v: float | None) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{v:.3f}"


def _label(name: str) -> str:
    return LABELS.get(name, {"bdew_average_gross_eur_per_kwh": "BDEW average",
                             "bnetza_average_gross_eur_per_kwh": "Bundesnetzagentur average"}.get(name, name))


def _published(tables: Tables, year: int, field: str) -> float | None:
    entry = tables.data.years.get(str(year))
    item: Sourced | None = getattr(entry, field) if entry is not None else None
    return item.halves[0] if item is not None and item.known else None


def _blend(a: float | None, b: float | None, share_a: float) -> float | None:
    """Hour-weighted mean of the two calendar years' averages (None unless both are known)."""
    return None if a is None or b is None else share_a * a + (1.0 - share_a) * b


def winters_table(rows: Sequence[WinterPrices], tables: Tables) -> str:
    """Each winter's mean buy price beside the published averages and its feed-in rate [EUR/kWh]."""
    lines = [
        "| winter | tariff | day-ahead mean | buy mean | household tariff mean | least buy | hours < 0 | "
        "hours buy < sell | sell (feed-in) | BDEW Y / Y+1 | BDEW, hour-weighted | Bundesnetzagentur Y / Y+1 | "
        "Bundesnetzagentur, hour-weighted |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        y0, y1 = r.winter, r.winter + 1
        bdew = (_published(tables, y0, "bdew_average_gross_eur_per_kwh"),
                _published(tables, y1, "bdew_average_gross_eur_per_kwh"))
        bnetza = (_published(tables, y0, "bnetza_average_gross_eur_per_kwh"),
                  _published(tables, y1, "bnetza_average_gross_eur_per_kwh"))
        lines.append(
            f"| {y0}/{y1 % 100:02d} | {r.tariff} | {_eur(r.spot_mean)} | {_eur(r.buy_mean)} | "
            f"{_eur(r.household_mean)} | {_eur(r.buy_min)} | {r.negative_h} | {r.below_sell_h} | {_eur(r.sell)} | "
            f"{_eur(bdew[0])} / {_eur(bdew[1])} | {_eur(_blend(*bdew, r.december_share))} | "
            f"{_eur(bnetza[0])} / {_eur(bnetza[1])} | {_eur(_blend(*bnetza, r.december_share))} |")
    return "\n".join(lines)


def _ct(item: Sourced | None, scale: float = CT_PER_EUR) -> str:
    if item is None or not item.known:
        return "–"
    first, second = item.halves
    if first == second:
        return f"{first * scale:.3f}".rstrip("0").rstrip(".") if first else "0"
    return f"{first * scale:g} / {second * scale:g}"


def components_table(tables: Tables) -> str:
    """The components of every year [ct/kWh net; shares in %] with the gross price at a spot price of 0."""
    fields = (*NET_COMPONENTS, "spot_surcharge_share", "vat_share", "feed_in_dec_eur_per_kwh")
    head = " | ".join(LABELS[f] for f in fields)
    lines = [f"| year | {head} | buy at spot 0 (Jan, gross) |", "|---|" + "---:|" * (len(fields) + 1)]
    for year in sorted(tables.data.years):
        entry = tables.data.years[year]
        cells = " | ".join(_ct(getattr(entry, f)) for f in fields)
        lines.append(f"| {year} | {cells} | {non_energy_gross(entry, JANUARY) * CT_PER_EUR:.2f} |")
    return "\n".join(lines)


def _years(years: Sequence[int]) -> str:
    """``[2015, 2016, 2017, 2019]`` -> ``2015-2017, 2019``."""
    runs: list[list[int]] = []
    for y in sorted(years):
        if runs and y == runs[-1][-1] + 1:
            runs[-1].append(y)
        else:
            runs.append([y])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)


def sources_table(tables: Tables) -> str:
    """Which source each field of each year names, then the sources in full."""
    used: dict[str, dict[str, list[int]]] = {}
    notes = []
    for year in sorted(tables.data.years):
        entry = tables.data.years[year]
        for name, item in entry.sourced().items():
            used.setdefault(item.source, {}).setdefault(_label(name), []).append(int(year))
            if item.note:
                notes.append(f"- {_label(name)} {year}: {item.note}")
        if entry.note:
            notes.append(f"- {year}: {entry.note}")
    lines = ["| source | for | reference |", "|---|---|---|"]
    for key, text in tables.data.sources.items():
        what = "; ".join(f"{label} {_years(ys)}" for label, ys in used.get(key, {}).items()) or "–"
        lines.append(f"| `{key}` | {what} | {text.replace('|', chr(92) + '|')} |")
    return "\n".join(lines + ([""] + notes if notes else []))


def tariff_section(rows: Sequence[WinterPrices], tables: Tables) -> str:
    """The generated section: winters, components, sources (the file they come from named)."""
    return "\n\n".join((
        f"Generated by `comems4build data tariffs` from `config/{tables.path.name}` and the winters' "
        "day-ahead prices; prices in EUR/kWh, the published averages gross for 3,500 kWh/a (BDEW) or "
        "2,500-5,000 kWh/a on 1 April (Bundesnetzagentur), '–' where no source was found.",
        winters_table(rows, tables),
        "The components of each year, ct/kWh net of VAT (a change on 1 July shown as January-June / "
        "July-December), the shares in per cent:",
        components_table(tables).replace("| spot surcharge | VAT |", "| spot surcharge [%] | VAT [%] |"),
        sources_table(tables),
    ))
