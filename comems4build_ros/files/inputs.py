"""Reading input files: one YAML loader and one JSON loader for every file the project reads.

Every YAML the project reads (parameter files given with ``--config``, cost files, topic
maps, live-input settings, the topic contract, a bag's ``run_info.json`` and the files it
names, ``--set`` values) goes through :func:`load_yaml_text` / :func:`load_yaml_file`, and
every JSON document (aWATTar answers, bag messages, ``run_info.json``, ``reproduce.json``,
run records, summaries) through :func:`load_json_text` / :func:`load_json_file`. They bound
what a crafted or damaged file can cost before any of it reaches Python objects:

- size: a file larger than :data:`MAX_FILE_BYTES` is refused before it is read;
- nesting: more than :data:`MAX_DEPTH` levels of sequences and mappings (a deep
  ``[[[[...]]]]`` would end Python's recursion in the parser or in the code that walks it);
- YAML aliases: at most :data:`MAX_ALIASES` aliases, none to a collection that is still open
  (a recursive alias, ``&a [*a]``), and at most :data:`MAX_NODES` nodes once every alias is
  expanded (a chain of aliases that doubles at each level, "billion laughs", would grow
  memory until the process is killed);
- YAML keys: a mapping key must be a string (``1:``, ``true:``, ``null:`` or ``[a]:`` is
  refused) and must not repeat in one mapping (PyYAML keeps the last one silently);
- one YAML document per file.

The limits are checked on libyaml's event stream, which parses without recursion, before
the document is composed; JSON's nesting is measured on the text before :mod:`json` parses
it. Each refusal is an :class:`InputFileError` naming the file, the line and the column
(YAML; JSON: line and column from :mod:`json`, or the offset of the bracket that is too deep).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import yaml

from comems4build_ros.files.errors import InputError

#: libyaml's safe loader where PyYAML has it (same documents, about 10x faster: every node
#: process parses the contract and the plant parameters at start-up), else the Python one.
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

#: Largest input file read [bytes]: every shipped input is below 2 MB (the year's scenario
#: CSV); a bag's message payloads are far smaller.
MAX_FILE_BYTES = 256 * 1024 * 1024
#: Largest YAML or JSON document [bytes] (parameter files, topic maps, JSON records).
MAX_DOCUMENT_BYTES = 16 * 1024 * 1024
#: Deepest nesting of sequences and mappings in a YAML or JSON document (the shipped files
#: nest at most 7 levels).
MAX_DEPTH = 64
#: Most aliases in one YAML document (the shipped files use none).
MAX_ALIASES = 1000
#: Most nodes of one YAML document with every alias expanded (the largest shipped file,
#: config/reproduce.yaml, has under 1000).
MAX_NODES = 100_000

#: White space in the text inputs: ASCII space, tab, carriage return, line feed (the only
#: characters allowed around a number, see :func:`parse_decimal`).
ASCII_SPACE = " \t\r\n"

_STR = "tag:yaml.org,2002:str"
_MERGE = "tag:yaml.org,2002:merge"


class InputFileError(InputError):
    """A file that cannot be read as the input it should be; the message names the file and where.

    ``problem``: the reason alone, without the source (for messages that name it their own way).
    """

    def __init__(self, message: str, problem: str = "") -> None:
        super().__init__(message)
        self.problem = problem or message


def _located(source: str, mark: Any, problem: str) -> InputFileError:
    """An :class:`InputFileError` at ``source:line:column`` of ``mark``."""
    return InputFileError(f"{_where(source, mark)}: {problem}", problem)


def _yaml_error(source: str, exc: yaml.YAMLError) -> InputFileError:
    """An :class:`InputFileError` of a PyYAML error: source, line, column and the problem in one line."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    context = getattr(exc, "context", None)
    text = f"{problem} ({context})" if context else str(problem)
    return InputFileError(f"{_where(source, mark)}: invalid YAML: {text}", text)


def _where(source: str, mark: Any) -> str:
    """``source:line:column`` of a YAML mark (1-based)."""
    if mark is None:
        return source
    return f"{source}:{mark.line + 1}:{mark.column + 1}"


def read_text(path: str | Path, what: str, max_bytes: int = MAX_DOCUMENT_BYTES, encoding: str = "utf-8",
              data_file: bool = False) -> str:
    """The text of the regular file ``path``, at most ``max_bytes``, decoded with ``encoding``.

    ``data_file``: also refuse NUL bytes (binary content in a Latin-1 file, which decodes) and
    a file with nothing but white space (data files: scenario CSV, DWD, DHWCalc, JSON).

    Raises
    ------
    InputFileError
        Naming the file and ``what`` it should be: no such file, a directory, a device, FIFO
        or socket, unreadable, larger than ``max_bytes``, not text in ``encoding`` or, with
        ``data_file``, binary or empty.
    """
    path = Path(path)
    kind = path_kind(path)
    if kind:
        raise InputFileError(f"{path}: cannot read {what}: {kind}")
    try:
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if len(data) > max_bytes:
        raise InputFileError(f"{path}: cannot read {what}: larger than {max_bytes} bytes")
    if data_file and b"\0" in data:
        raise InputFileError(f"{path}: cannot read {what}: binary content (NUL bytes), not a text file")
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputFileError(
            f"{path}: cannot read {what}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset "
            f"{exc.start}); a binary file?"
        ) from None
    if data_file and not text.strip(ASCII_SPACE + "\ufeff"):
        raise InputFileError(f"{path}: cannot read {what}: empty file")
    return text


def between_markers(text: str, begin: str, end: str, where: str) -> tuple[str, str]:
    """``(head, tail)`` around the block between the markers ``begin`` and ``end`` of a document.

    Each marker must stand once, ``begin`` before ``end``; a document written by hand around
    a generated block (``--update-doc``) is refused otherwise, before any work.

    Raises
    ------
    InputFileError
        Naming ``where`` (the option and file) and what is wrong with the markers.
    """
    counts = {m: text.count(m) for m in (begin, end)}
    if any(n != 1 for n in counts.values()):
        said = ", ".join(f"{m} {'missing' if n == 0 else f'{n} times'}" for m, n in counts.items() if n != 1)
        raise InputFileError(f"{where}: markers {begin} / {end} must each stand once ({said})")
    head, _, rest = text.partition(begin)
    if end not in rest:
        raise InputFileError(f"{where}: marker {end} stands before {begin}")
    return head, rest.partition(end)[2]


def check_markers(path: str | Path, begin: str, end: str, option: str) -> None:
    """The document ``path`` of ``option`` is readable UTF-8 text with the markers (:func:`between_markers`).

    Raises
    ------
    InputFileError
        Naming the option, the file and the problem.
    """
    between_markers(read_text(path, f"the document of {option}"), begin, end, f"{option} {path}")


def path_kind(path: str | Path) -> str:
    """Why ``path`` cannot be read as a data file (``""`` if it is an existing regular file).

    ``"no such file"``, ``"is a directory"`` or ``"is not a regular file (a device, FIFO or
    socket)"``, e.g. for ``/dev/null``.
    """
    p = Path(path)
    try:
        if p.is_dir():
            return "is a directory"
        if not p.exists():
            return "no such file"
        if not p.is_file():
            return "is not a regular file (a device, FIFO or socket)"
    except OSError as exc:  # a name too long, a loop of symbolic links
        return exc.strerror or str(exc)
    return ""


# ---------------------------------------------------------------------------------------- YAML
def _check_events(text: str, source: str) -> None:
    """Depth, aliases and expanded size of a YAML text, on libyaml's event stream (no recursion).

    Raises
    ------
    InputFileError
        Naming ``source``, line and column of the first node over a limit.
    """
    # per open collection: [anchor, expanded node count so far]
    stack: list[list[Any]] = []
    sizes: dict[str, int] = {}  # anchor -> expanded node count of its (closed) node
    aliases = 0
    documents = 0
    total = 0
    try:
        for event in yaml.parse(text, Loader=SAFE_LOADER):
            if isinstance(event, yaml.DocumentStartEvent):
                documents += 1
                if documents > 1:
                    raise _located(source, event.start_mark, "more than one YAML document "
                                         "(a '---' line inside the file?)")
                continue
            if isinstance(event, yaml.CollectionStartEvent):
                stack.append([event.anchor, 1])
                if len(stack) > MAX_DEPTH:
                    raise _located(source, event.start_mark, f"nested more than {MAX_DEPTH} levels "
                                         "deep")
                continue
            if isinstance(event, yaml.CollectionEndEvent):
                anchor, size = stack.pop()
                if anchor is not None:
                    sizes[anchor] = size
                if stack:
                    stack[-1][1] += size
                total = max(total, size)
            elif isinstance(event, yaml.AliasEvent):
                aliases += 1
                if aliases > MAX_ALIASES:
                    raise _located(source, event.start_mark, f"more than {MAX_ALIASES} YAML "
                                         "aliases")
                if any(entry[0] == event.anchor for entry in stack):
                    raise _located(source, event.start_mark, f"the alias *{event.anchor} refers "
                                         "to a node that contains it (a recursive alias)")
                if event.anchor not in sizes:  # a scalar's anchor, or undefined (the composer names it)
                    size = 1
                else:
                    size = sizes[event.anchor]
                if stack:
                    stack[-1][1] += size
                total = max(total, size)
            elif isinstance(event, yaml.ScalarEvent):
                if event.anchor is not None:
                    sizes[event.anchor] = 1
                if stack:
                    stack[-1][1] += 1
            else:
                continue
            if (stack and stack[-1][1] > MAX_NODES) or total > MAX_NODES:
                raise _located(source, event.start_mark, f"more than {MAX_NODES} nodes with "
                                     "its aliases expanded (an alias chain that multiplies the document?)")
    except yaml.YAMLError as exc:
        raise _yaml_error(source, exc) from None


def _check_keys(node: yaml.Node, source: str) -> None:
    """Every mapping key of the composed document a string, each once per mapping (iterative)."""
    seen: set[int] = set()
    todo = [node]
    while todo:
        n = todo.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        if isinstance(n, yaml.MappingNode):
            keys: dict[str, Any] = {}
            for key, value in n.value:
                if key.tag == _MERGE:
                    todo.append(value)
                    continue
                if not isinstance(key, yaml.ScalarNode) or key.tag != _STR:
                    shown = key.value if isinstance(key, yaml.ScalarNode) else f"a {key.id}"
                    raise _located(source, key.start_mark, f"key {shown!r} is not a string "
                                         "(write it in quotes if it is meant as a name)")
                if key.value in keys:
                    first = keys[key.value]
                    raise _located(source, key.start_mark, f"key '{key.value}' given twice in one "
                                         f"mapping (first at line {first.line + 1}, column {first.column + 1})")
                keys[key.value] = key.start_mark
                todo.append(value)
        elif isinstance(n, yaml.SequenceNode):
            todo.extend(n.value)


def load_yaml_text(text: str, source: str) -> Any:
    """Parse one YAML document within the limits of this module.

    Parameters
    ----------
    text : the document
    source : what it is, for messages (a file name, ``--set battery.e_max_kwh=...``)

    Returns
    -------
    The document as Python data (``None`` for an empty document).

    Raises
    ------
    InputFileError
        Naming ``source``, line and column: invalid YAML, over a limit, a key that is not
        a string or given twice in one mapping, more than one document.
    """
    if len(text) > MAX_DOCUMENT_BYTES:
        raise InputFileError(f"{source}: larger than {MAX_DOCUMENT_BYTES} bytes")
    _check_events(text, source)
    loader = SAFE_LOADER(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_keys(node, source)
        return loader.construct_document(node)
    except yaml.YAMLError as exc:
        raise _yaml_error(source, exc) from None
    except RecursionError:  # not reached within MAX_DEPTH; a last guard
        raise InputFileError(f"{source}: nested too deeply") from None
    finally:
        loader.dispose()


def load_yaml_file(path: str | Path, what: str) -> Any:
    """Read and parse the YAML file ``path`` (:func:`read_text`, :func:`load_yaml_text`).

    ``what`` says what the file should be (``parameter file``, ``topic map``); it is named in
    messages about the file as a whole.
    """
    return load_yaml_text(read_text(path, what), str(path))


# ---------------------------------------------------------------------------------------- JSON
_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.DOTALL)
_JSON_BRACKET = re.compile(r"[\[\]{}]")


def json_depth_error(text: str) -> str | None:
    """Why ``text`` nests deeper than :data:`MAX_DEPTH` (the offset of the first bracket too deep), or None."""
    if text.count("[") + text.count("{") <= MAX_DEPTH:
        return None
    depth = 0
    for m in _JSON_BRACKET.finditer(_JSON_STRING.sub(lambda s: " " * len(s.group()), text)):
        depth += 1 if m.group() in "[{" else -1
        if depth > MAX_DEPTH:
            line = text.count("\n", 0, m.start()) + 1
            column = m.start() - (text.rfind("\n", 0, m.start()) + 1) + 1
            return f"line {line} column {column}: nested more than {MAX_DEPTH} levels deep"
    return None


def load_json_text(text: str | bytes, source: str) -> Any:
    """Parse a JSON document within the size and depth limits of this module.

    Raises
    ------
    InputFileError
        Naming ``source`` and the line and column: invalid JSON, not UTF-8, too large, too deep.
    """
    if isinstance(text, bytes | bytearray):
        try:
            text = bytes(text).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputFileError(f"{source}: not UTF-8 text (byte at offset {exc.start})") from None
    if len(text) > MAX_DOCUMENT_BYTES:
        raise InputFileError(f"{source}: larger than {MAX_DOCUMENT_BYTES} bytes")
    deep = json_depth_error(text)
    if deep:
        raise InputFileError(f"{source}: {deep}")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputFileError(f"{source}: line {exc.lineno}: invalid JSON: {exc.msg} (column {exc.colno})",
                             f"line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    except RecursionError:  # not reached within MAX_DEPTH; a last guard
        raise InputFileError(f"{source}: nested too deeply") from None


def load_json_file(path: str | Path, what: str) -> Any:
    """Read and parse the JSON file ``path`` (:func:`read_text`, :func:`load_json_text`)."""
    return load_json_text(read_text(path, what), str(path))



#: A plain decimal number as the text sources write it (DWD and DHWCalc files, MQTT
#: ``number`` commands, command-line lists): ASCII digits, an optional sign, point and
#: exponent. Python's own ``float``/``int`` also take forms no such source writes and that
#: signal a damaged or crafted input: digit groups (``1_000``), digits of other scripts
#: (``١٢``), ``nan``/``inf`` spelled out, and surroundings of Unicode space or control
#: characters (``\x1c``, no-break space) that ``str.strip`` removes.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")


def parse_decimal(text: str) -> float:
    """The value [as written] of ``text``, a plain decimal number (``"12"``, ``"-0.5"``, ``"1e3"``).

    Only ASCII space, tab, CR and LF may surround it. Raises ``ValueError`` (whose message
    quotes the text) for anything else, including the forms Python's ``float`` accepts beyond
    plain decimals (see :data:`_DECIMAL`); the caller names the file, line, field or topic.
    """
    core = text.strip(ASCII_SPACE)
    if _DECIMAL.fullmatch(core) is None:
        raise InputError(f"{text[:40]!r} is not a plain decimal number")
    return float(core)


def parse_integer(text: str) -> int:
    """The value of ``text``, a plain decimal integer (ASCII digits, optional sign, ASCII space around).

    Raises ``ValueError`` for anything else (``"1_0"``, ``"١٢"``, ``"0x10"``, ``"1.0"``).
    """
    core = text.strip(ASCII_SPACE)
    if _INTEGER.fullmatch(core) is None:
        raise InputError(f"{text[:40]!r} is not a plain decimal integer")
    return int(core)


def text_lines(text: str) -> list[str]:
    """The lines of ``text`` as an editor numbers them: split at LF only, a trailing CR dropped.

    ``str.splitlines`` also splits at the ASCII separators ``\\x1c``-``\\x1e``, ``\\x85`` and
    U+2028/U+2029, so a stray one in a data file would shift every line number after it in
    the error messages that name a line (and hide the damage as a short line).
    """
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]
