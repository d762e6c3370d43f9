"""The README's command table, generated from the argparse parsers of every subcommand.

``python -m comems4build_ros.app.commands.table --update-doc README.md`` rewrites the block
between ``<!-- commands:begin -->`` and ``<!-- commands:end -->``; a test checks that the
README holds what :func:`command_table` generates, so no option can be missing there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

BEGIN = "<!-- commands:begin -->"
END = "<!-- commands:end -->"


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # noqa: SLF001 (argparse offers no public accessor)
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            return dict(action.choices)
    return {}


def _help_of(parser: argparse.ArgumentParser, name: str) -> str:
    for action in parser._actions:  # noqa: SLF001
        if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
            for choice in action._choices_actions:  # noqa: SLF001
                if choice.dest == name:
                    return str(choice.help or "")
    return ""


def option_text(action: argparse.Action) -> str:
    """``--weeks N``, ``[--no-progress]``, ``--via inprocess|ros``, ``[--config FILE ...]`` or ``BAG``."""
    if not action.option_strings:
        return str(action.metavar or action.dest).upper()
    flag = max(action.option_strings, key=len)
    if action.nargs == 0:
        text = flag
    else:
        if action.choices is not None:
            value = "|".join(str(c) for c in action.choices)
        else:
            value = str(action.metavar or action.dest.upper())
        text = f"{flag} {value}"
        if isinstance(action, argparse._AppendAction):  # noqa: SLF001
            text += " ..."
    return text if action.required else f"[{text}]"


def options_of(parser: argparse.ArgumentParser) -> list[str]:
    """Every option of ``parser`` (help excluded) in definition order; exclusive ones as ``[--a A | --b B]``."""
    groups = {id(a): g for g in parser._mutually_exclusive_groups for a in g._group_actions}  # noqa: SLF001
    out: list[str] = []
    done: set[int] = set()
    for action in parser._actions:  # noqa: SLF001
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):  # noqa: SLF001
            continue
        group = groups.get(id(action))
        if group is None:
            out.append(option_text(action))
        elif id(group) not in done:
            done.add(id(group))
            parts = [option_text(a).strip("[]") for a in group._group_actions]  # noqa: SLF001
            out.append(f"[{' | '.join(parts)}]")
    return out


def rows() -> list[tuple[str, list[str], str]]:
    """``(command, options, help)`` of every subcommand and of the actions of ``bench`` and ``data``."""
    from comems4build_ros.app.cli import build_parser

    top = build_parser()
    out = []
    for name, parser in _subparsers(top).items():
        nested = _subparsers(parser)
        if nested:
            for sub, p in nested.items():
                out.append((f"{name} {sub}", options_of(p), _help_of(parser, sub)))
        else:
            out.append((name, options_of(parser), _help_of(top, name)))
    return out


def command_table() -> str:
    """The markdown table: one row per command with all its options and its help text."""
    lines = ["| command | options | what it does |", "|---|---|---|"]
    for name, opts, text in rows():
        cell = " ".join(f"`{o}`" for o in opts).replace("|", "\\|")
        lines.append(f"| `comems4build {name}` | {cell} | {text.replace('|', chr(92) + '|')} |")
    return "\n".join(lines)


def update_doc(path: str | Path) -> bool:
    """Replace the block between the markers in ``path``; True if the file changed."""
    from comems4build_ros.files.inputs import InputFileError, between_markers, read_text
    from comems4build_ros.files.outputs import write_text_atomic

    p = Path(path)
    try:
        text = read_text(p, "a document with the command table")
        head, tail = between_markers(text, BEGIN, END, str(p))
    except InputFileError as exc:
        raise SystemExit(str(exc)) from None
    new = f"{head}{BEGIN}\n{command_table()}\n{END}{tail}"
    if new != text:
        write_text_atomic(p, new)
    return new != text


def main(argv: list[str] | None = None) -> int:
    """Print the table, or rewrite it in a document with ``--update-doc FILE``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--update-doc", metavar="FILE", help="rewrite the table between the markers in FILE")
    args = parser.parse_args(argv)
    if args.update_doc:
        changed = update_doc(args.update_doc)
        print(f"{args.update_doc}: {'updated' if changed else 'already current'}")
    else:
        print(command_table())
    return 0


if __name__ == "__main__":
    sys.exit(main())
