"""`urdf-pipeline init`: scaffold a config from a URDF, optionally pre-matched to a source's names.

The result is YAML text with comments, generated here (not dumped) so that every guess carries its reason:
`# TODO: ...` marks what init could not know (a stub to fill in, a decision to make: an ignored name, a held joint,
the calibration edge), `# review: ...` a guess to check (a name match and its score, a unit). `validate` refuses
the result only on stubs that cannot work as they are, all marked TODO: the stub source file (which does not exist),
a package folder init could not find. The text is deterministic for a given URDF, source and output location.

SOURCE_SPEC is `KIND:PATH[#PART]` (PATH relative to the current directory, PART chosen per kind):

- `lerobot:DIR[#FEATURE]`   a LeRobot dataset; FEATURE default `observation.state`; names from meta/info.json
- `parquet:FILE[#COLUMN]`   COLUMN default `observation.state` (or the file's only list column); parquet has no names
- `mcap:FILE[#TOPIC]`       TOPIC default: the file's only sensor_msgs/msg/JointState topic; names from its first message
- `hdf5:FILE#/DATASET`      a 2-D dataset, e.g. `/observations/qpos`; HDF5 has no names
- `rrd:FILE#ENTITY`         e.g. `/observation.state`; names from the entity's SeriesLines:names

`KIND:` may be left out when the path says it (`.parquet`, `.mcap`, `.h5`/`.hdf5`, `.rrd`, a directory holding
meta/info.json). A glob in a file path (`data/*.parquet`) becomes a globbed source, one segment per file.
Only metadata is read, as `validate` reads it (a parquet schema, meta/info.json, the MCAP summary and the names of the
topic's first message, HDF5 shapes, the RRD manifest and names), never joint values.

Sources with names are matched to the URDF's joints by name similarity (see `match_names`); sources without names
(parquet, HDF5, a LeRobot feature without names) are matched by position and get the URDF joint names as `names`.

The `# yaml-language-server: $schema=...` line points at the nearest `schemas/urdf-pipeline.schema.json` found in the
output's folder or one of its parents (this repository's, or a copy vendored in the user's repository), as a relative
path; otherwise at the schema installed with the package, as an absolute path.
"""

from __future__ import annotations

import difflib
import glob
import json
import os
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import yaml

from ..config.document import Document, parse_document
from ..config.schema import SCHEMA_RESOURCE
from ..errors import UserError, listing
from ..urdf.meshes import package_roots
from ..urdf.model import Joint, UrdfModel, UrdfParseError, read_urdf

KINDS = ("lerobot", "parquet", "mcap", "hdf5", "rrd")
GLOB = re.compile(r"[*?\[]")
IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")
MATCH_CUTOFF = 0.75  # normalised names at least this similar (difflib ratio) are pre-matched, for review
SCHEMA_IN_REPO = Path("schemas") / SCHEMA_RESOURCE
STUB_SOURCE_DIR = "TODO"  # the stub parquet path starts here: it does not exist, so validate fails on it alone


# ---------------------------------------------------------------------------------------------------------------
# A tiny YAML emitter: nodes with comments -> text. Block mappings and sequences, flow lists and flow mappings.


@dataclass
class Item:
    key: str
    value: Any  # a scalar, a list (flow), a dict (flow), a Block or a Seq
    comment: str = ""


@dataclass
class Note:
    text: str


@dataclass
class Block:
    items: list[Item | Note] = field(default_factory=list)

    def add(self, key: str, value: Any, comment: str = "") -> None:
        self.items.append(Item(key, value, comment))

    def note(self, text: str) -> None:
        self.items.append(Note(text))


@dataclass
class Seq:
    items: list[tuple[Any, str]] = field(default_factory=list)  # (value, comment); value a scalar or a Block


_PLAIN = re.compile(r"^[A-Za-z0-9_./{}-][A-Za-z0-9_./:{}-]*$")


def scalar(value: Any, flow: bool = True) -> str:
    """A YAML scalar: plain when it reads back as the same string (in flow context: without `{}`), else double-quoted."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return number(value)
    if isinstance(value, int):
        return str(value)
    text = str(value)
    plain = bool(_PLAIN.match(text)) and not text.startswith(("{", "-")) and not text.endswith(":")
    if flow and ("{" in text or "}" in text):
        plain = False
    if text.startswith("."):  # ../x is plain, .inf is not
        plain = plain and text.startswith(("./", "../"))
    try:
        if plain and yaml.safe_load(f"k: {text}") == {"k": text}:
            return text
    except yaml.YAMLError:
        pass
    return json.dumps(text)  # a JSON string is a valid double-quoted YAML scalar


def number(value: float) -> str:
    """The shortest form that reads back as the same float, never in exponent form (YAML 1.1 reads 1e-05 as a string)."""
    text = repr(float(value))
    if "e" in text or "E" in text:
        text = f"{float(value):.15f}".rstrip("0")
        text = text + "0" if text.endswith(".") else text
    return text


def _flow(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{scalar(k)}: {_flow(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    return scalar(value)


def _flow_lines(prefix: str, values: list[Any], indent: int, width: int = 110) -> list[str]:
    """`key: [a, b, c]`, wrapped onto continuation lines when long."""
    parts = [_flow(v) for v in values]
    one = prefix + "[" + ", ".join(parts) + "]"
    if len(one) <= width:
        return [one]
    lines, line = [], prefix + "["
    pad = " " * (indent + 2)
    for i, part in enumerate(parts):
        piece = part + ("," if i < len(parts) - 1 else "]")
        if i and len(line) + 1 + len(piece) > width:
            lines.append(line)
            line = pad + piece
        else:
            line += (" " if i else "") + piece
    lines.append(line)
    return lines


def _with_comments(bodies: list[tuple[str, str]]) -> list[str]:
    """Align the comments of one block's lines (a body longer than 60 characters is not waited for)."""
    widths = [len(body) for body, comment in bodies if comment and len(body) <= 60]
    column = max(widths, default=0) + 3
    out = []
    for body, comment in bodies:
        if not comment:
            out.append(body)
        else:
            gap = max(column - len(body), 3)
            out.append(body + " " * gap + "# " + comment)
    return out


def render_block(block: Block, indent: int = 0) -> list[str]:
    pad = " " * indent
    bodies: list[tuple[str, str]] = []
    nested: list[list[str]] = []  # lines following each body (nested blocks), aligned separately

    for item in block.items:
        if isinstance(item, Note):
            bodies.append((pad + "# " + item.text, ""))
            nested.append([])
        elif isinstance(item.value, (Block, Seq)):
            bodies.append((f"{pad}{scalar(item.key)}:", item.comment))
            nested.append(render_block(item.value, indent + 2) if isinstance(item.value, Block) else render_seq(item.value, indent + 2))
        elif isinstance(item.value, (list, tuple)):
            lines = _flow_lines(f"{pad}{scalar(item.key)}: ", list(item.value), indent)
            if len(lines) == 1:
                bodies.append((lines[0], item.comment))
                nested.append([])
            else:  # wrapped: the comment goes on the last line
                bodies.append((lines[0], ""))
                nested.append(lines[1:-1] + _with_comments([(lines[-1], item.comment)]))
        else:
            shown = scalar(item.value, flow=False) if isinstance(item.value, str) else _flow(item.value)
            bodies.append((f"{pad}{scalar(item.key)}: {shown}", item.comment))
            nested.append([])
    aligned = _with_comments(bodies)
    out: list[str] = []
    for line, after in zip(aligned, nested, strict=True):
        out.append(line)
        out.extend(after)
    return out


def render_seq(seq: Seq, indent: int) -> list[str]:
    pad = " " * indent
    out: list[str] = []
    scalars: list[tuple[str, str]] = []  # a run of scalar items, their comments aligned together
    for value, comment in seq.items:
        if isinstance(value, Block):
            out.extend(_with_comments(scalars))
            scalars = []
            lines = render_block(value, indent + 2)
            out.append(pad + "- " + lines[0][indent + 2 :])
            out.extend(lines[1:])
        else:
            scalars.append((f"{pad}- {_flow(value)}", comment))
    return out + _with_comments(scalars)


def to_data(node: Any) -> Any:
    """The plain data a node stands for (what a YAML parser should read back)."""
    if isinstance(node, Block):
        return {item.key: to_data(item.value) for item in node.items if isinstance(item, Item)}
    if isinstance(node, Seq):
        return [to_data(value) for value, _ in node.items]
    if isinstance(node, (list, tuple)):
        return [to_data(v) for v in node]
    if isinstance(node, dict):
        return {k: to_data(v) for k, v in node.items()}
    return node


# ---------------------------------------------------------------------------------------------------------------
# Name matching


@dataclass(frozen=True)
class NameKey:
    side: str  # "left", "right" or ""
    tokens: tuple[str, ...]

    @property
    def numbers(self) -> tuple[str, ...]:
        return tuple(t for t in self.tokens if t.isdigit())

    @property
    def text(self) -> str:
        return "_".join(self.tokens)


_CAMEL = re.compile(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")
_JOINT_WORDS = {"joint", "jnt", "j"}
_SIDES = {"l": "left", "left": "left", "lft": "left", "r": "right", "right": "right", "rgt": "right", "rt": "right"}


def name_tokens(name: str) -> list[str]:
    """`kLeftShoulderPitch` -> left shoulder pitch; `wrist_1_joint` -> wrist 1 joint; `Joint8.0` -> joint 8 0."""
    name = re.sub(r"^k(?=[A-Z])", "", name)  # Unitree's constant style: kLeftElbow
    name = _CAMEL.sub("_", name)
    return [piece for part in re.split(r"[^A-Za-z0-9]+", name.lower()) if part for piece in re.findall(r"[a-z]+|[0-9]+", part)]


def name_key(name: str) -> NameKey:
    """Lowercase tokens without joint words (`joint_`, `_joint`, `j1`), the side (`left_`, `l_`, `_r`) apart."""
    tokens = name_tokens(name)
    kept = [t for t in tokens if t not in _JOINT_WORDS] or tokens
    side = ""
    if len(kept) > 1 and kept[0] in _SIDES:
        side, kept = _SIDES[kept[0]], kept[1:]
    elif len(kept) > 1 and kept[-1] in _SIDES:
        side, kept = _SIDES[kept[-1]], kept[:-1]
    return NameKey(side, tuple(kept))


def _strip_common(keys: list[NameKey]) -> list[NameKey]:
    """Drop the leading and trailing tokens every name of a list shares (`panda` of `panda_joint1`..`panda_finger_joint1`,
    `pos` of `shoulder_pan.pos`..`gripper.pos`), as long as every name keeps one."""
    if len(keys) < 2:
        return keys
    for end in (0, -1):
        while all(len(k.tokens) > 1 for k in keys) and len({k.tokens[end] for k in keys}) == 1 and not keys[0].tokens[end].isdigit():
            keys = [NameKey(k.side, k.tokens[1:] if end == 0 else k.tokens[:-1]) for k in keys]
    return keys


def similarity(a: NameKey, b: NameKey) -> float:
    """0..1: the mean of the character and the word similarity (difflib) of the normalised names. Different sides, or
    different numbers (wrist_1 vs wrist_2), never match; numbers on one side only are left out; one side unknown costs 10 %."""
    if a.side and b.side and a.side != b.side:
        return 0.0
    if a.numbers and b.numbers and a.numbers != b.numbers:
        return 0.0
    words_a, words_b = list(a.tokens), list(b.tokens)
    if not (a.numbers and b.numbers):
        words_a = [t for t in words_a if not t.isdigit()] or words_a
        words_b = [t for t in words_b if not t.isdigit()] or words_b
    chars = difflib.SequenceMatcher(None, "_".join(words_a), "_".join(words_b)).ratio()
    words = difflib.SequenceMatcher(None, words_a, words_b).ratio()
    return (chars + words) / 2 * (0.9 if bool(a.side) != bool(b.side) else 1.0)


@dataclass(frozen=True)
class Match:
    source_name: str
    joint: str
    score: float


def match_names(source_names: list[str], joints: list[str], cutoff: float = MATCH_CUTOFF) -> list[Match]:
    """One-to-one pre-matching, best pairs first (identical names before equal scores), in source order.

    Each name is compared as is and without the leading and trailing tokens all names of its side share (`panda_` in
    `panda_joint1`..`panda_finger_joint1`, `.pos` in `shoulder_pan.pos`..`gripper.pos`); the best comparison counts.
    """
    source_keys = list(zip([name_key(n) for n in source_names], _strip_common([name_key(n) for n in source_names]), strict=True))
    joint_keys = list(zip([name_key(j) for j in joints], _strip_common([name_key(j) for j in joints]), strict=True))
    pairs = []
    for i, name in enumerate(source_names):
        for k, joint in enumerate(joints):
            score = 1.0 if name == joint else max(similarity(a, b) for a in set(source_keys[i]) for b in set(joint_keys[k]))
            if score >= cutoff:
                pairs.append((-round(score, 6), name != joint, i, k))
    used_sources: set[int] = set()
    used_joints: set[int] = set()
    matches: dict[int, Match] = {}
    for negative, _, i, k in sorted(pairs):
        if i not in used_sources and k not in used_joints:
            used_sources.add(i)
            used_joints.add(k)
            matches[i] = Match(source_names[i], joints[k], -negative)
    return [matches[i] for i in sorted(matches)]


# ---------------------------------------------------------------------------------------------------------------
# Sources: SOURCE_SPEC -> the config entry and the names, from metadata only


@dataclass
class SourceInfo:
    kind: str
    entry: Block  # the config's source entry (names added later for positional sources)
    names: list[str] | None  # names from the metadata; None: the source has none (matched by position)
    width: int | None  # values per row when known (positional sources)
    segment: str  # output.segment template
    notes: list[str] = field(default_factory=list)


def parse_source_spec(text: str) -> tuple[str, str, str | None]:
    """`KIND:PATH[#PART]` -> (kind, path, part); KIND inferred from PATH when left out."""
    kind, sep, rest = text.partition(":")
    if not sep or kind not in KINDS:
        kind, rest = "", text
    path, hash_, part = rest.partition("#")
    if not path:
        raise UserError(f"--source '{text}': no path; the form is KIND:PATH[#PART], KIND one of {', '.join(KINDS)}")
    if not kind:
        suffix = Path(path).suffix.lower()
        by_suffix = {".parquet": "parquet", ".mcap": "mcap", ".h5": "hdf5", ".hdf5": "hdf5", ".rrd": "rrd"}
        if suffix in by_suffix:
            kind = by_suffix[suffix]
        elif (Path(path) / "meta" / "info.json").is_file():
            kind = "lerobot"
        else:
            raise UserError(
                f"--source '{text}': say which kind of source it is: lerobot:DIR[#FEATURE], parquet:FILE[#COLUMN], "
                "mcap:FILE[#TOPIC], hdf5:FILE#/DATASET or rrd:FILE#ENTITY"
            )
    return kind, path, (part or None) if hash_ else None


def _relative(target: str | Path, base: Path) -> str:
    """`target` for a config in folder `base`: relative (as the pipeline resolves it, `(base / rel).resolve()`) when
    the two share a top folder, else absolute; with `/`."""
    real_base = os.path.realpath(base)
    real_target = os.path.realpath(target)
    absolute = os.path.abspath(target)
    options = []
    for path in (absolute, real_target):  # as given (keeping its symlinks), and resolved
        relative = os.path.relpath(path, real_base)
        shares_a_folder = os.path.commonpath([real_base, path]) != os.path.abspath(os.sep)
        if shares_a_folder and os.path.realpath(os.path.join(real_base, relative)) == real_target:
            options.append(relative)
    if not options:
        return Path(absolute).as_posix()
    return Path(min(options, key=len)).as_posix()  # the shorter; equal length: the one as given


def _relative_pattern(pattern: str, base: Path) -> str:
    folder, name = os.path.split(pattern)
    split = [i for i, part in enumerate(Path(pattern).parts) if GLOB.search(part)]
    if split and split[0] < len(Path(pattern).parts) - 1:  # a glob in a folder name: keep it as given, made absolute
        return Path(os.path.abspath(pattern)).as_posix()
    return f"{_relative(folder or '.', base)}/{name}".removeprefix("./")


def _document(out_file: Path) -> Document:
    return Document(out_file, {}, {})


def _reraise(text: str, exc: UserError) -> UserError:
    return UserError(f"--source {text}: {exc.message}")


def _first_file(text: str, path: str) -> Path:
    if GLOB.search(path):
        found = sorted(p for p in glob.glob(path, recursive=True) if Path(p).is_file())
        if not found:
            raise UserError(f"--source {text}: '{path}' matches no file")
        return Path(found[0]).resolve()
    resolved = Path(path).resolve()
    if not resolved.is_file():
        raise UserError(f"--source {text}: file not found: {resolved}")
    return resolved


def read_source(text: str, key: str, out_file: Path) -> SourceInfo:
    kind, path, part = parse_source_spec(text)
    base = out_file.parent
    globbed = kind != "lerobot" and bool(GLOB.search(path))
    config_path = _relative_pattern(path, base) if globbed else _relative(path, base)
    segment = "{stem}" if globbed else re.sub(r"[^A-Za-z0-9_.-]", "_", Path(path).name.split(".", 1)[0]) or "segment"
    entry = Block()
    entry.add(kind, config_path)
    if kind == "lerobot":
        return _lerobot(text, key, path, part, entry, out_file)
    file = _first_file(text, path)
    if kind == "parquet":
        return _parquet(text, file, part, entry, segment)
    if kind == "mcap":
        return _mcap(text, key, file, part, entry, segment, out_file)
    if kind == "hdf5":
        return _hdf5(text, key, file, part, entry, segment, out_file)
    return _rrd(text, key, file, part, entry, segment, out_file)


def _lerobot(text: str, key: str, path: str, part: str | None, entry: Block, out_file: Path) -> SourceInfo:
    from ..sources import lerobot

    feature = part or "observation.state"
    entry.add("feature", feature)
    root = Path(path).resolve()
    spec = {"lerobot": str(root), "feature": feature}
    info = SourceInfo("lerobot", entry, None, None, "episode_{episode:06d}")
    info.notes.append("no episode: one segment per episode of the dataset (episode: N pins one)")
    try:
        plan = lerobot.compile_source(key, spec, _document(out_file), root)
    except UserError as exc:
        width = _lerobot_unnamed_width(root, feature)
        if width is None:
            raise _reraise(text, exc) from None
        info.width = width  # a feature without names: matched by position, names given in the config
        return info
    info.names = list(plan.names)
    return info


def _lerobot_unnamed_width(root: Path, feature: str) -> int | None:
    from ..sources.lerobot import feature_names

    try:
        features = json.loads((root / "meta" / "info.json").read_text(encoding="utf-8")).get("features", {})
    except (OSError, json.JSONDecodeError):
        return None
    spec = features.get(feature)
    if not isinstance(spec, dict) or feature_names(spec) is not None:
        return None
    shape = spec.get("shape") or []
    return int(shape[0]) if len(shape) == 1 and isinstance(shape[0], int) else None


_SEQUENCE_COLUMNS = ("frame_index", "index", "frame", "step", "seq", "sequence")
_TIME_COLUMNS = ("timestamp", "time", "t", "stamp")


def _parquet(text: str, file: Path, part: str | None, entry: Block, segment: str) -> SourceInfo:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ..sources.parquet import _numeric_list_width

    try:
        schema = pq.read_schema(file)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"--source {text}: cannot read the parquet schema of {file}: {exc}") from None
    lists = [name for name in schema.names if _numeric_list_width(schema.field(name).type) is not False]
    if part is not None:
        column = part
    elif "observation.state" in lists:
        column = "observation.state"
    elif len(lists) == 1:
        column = lists[0]
    else:
        raise UserError(
            f"--source {text}: name the column with parquet:FILE#COLUMN; list columns of {file.name}: {listing(lists, empty='none')}"
        )
    if column not in schema.names:
        raise UserError(f"--source {text}: column '{column}' not in {file.name}; it has: {', '.join(schema.names)}")
    width = _numeric_list_width(schema.field(column).type)
    if width is False:
        raise UserError(f"--source {text}: column '{column}' is {schema.field(column).type}, not a list of numbers")
    entry.add("column", column)
    integers = [n for n in schema.names if pa.types.is_integer(schema.field(n).type)]
    times = [
        n
        for n in schema.names
        if pa.types.is_timestamp(schema.field(n).type) or (pa.types.is_floating(schema.field(n).type) and n.lower() in _TIME_COLUMNS)
    ]
    sequence = next((n for n in _SEQUENCE_COLUMNS if n in integers), None)
    if sequence is not None:
        entry.add("index", sequence, "review: the timeline column (a sequence); or {timestamp: COL, unit: s}")
    elif times:
        entry.add(
            "index", {"timestamp": times[0], "unit": "s"}, "review: time since the epoch; {duration: COL, unit: s} if it counts from 0"
        )
    else:
        entry.add("index", "frame_index", f"TODO: {file.name} has no frame or time column this could guess; name its timeline column")
    return SourceInfo("parquet", entry, None, width if isinstance(width, int) else None, segment)


def _mcap(text: str, key: str, file: Path, part: str | None, entry: Block, segment: str, out_file: Path) -> SourceInfo:
    from rerun.chunk import McapReader

    from ..sources import mcap

    topic = part
    if topic is None:
        try:
            channels = McapReader(file).info().channels
        except (ValueError, OSError, RuntimeError) as exc:
            raise UserError(f"--source {text}: cannot read MCAP file {file}: {exc}") from None
        topics = sorted({c.topic for c in channels if c.schema is not None and c.schema.name == mcap.JOINT_STATE})
        if len(topics) != 1:
            raise UserError(
                f"--source {text}: name the topic with mcap:FILE#TOPIC; its {mcap.JOINT_STATE} topics: {listing(topics, empty='none')}"
            )
        topic = topics[0]
    entry.add("topic", topic)
    try:
        plan = mcap.compile_source(key, {"mcap": str(file), "topic": topic}, _document(out_file), file.parent)
    except UserError as exc:
        raise _reraise(text, exc) from None
    info = SourceInfo("mcap", entry, list(plan.names), None, segment)
    info.notes.append("names: read from the topic's first message by validate (every name must be mapped or ignored)")
    return info


def _hdf5(text: str, key: str, file: Path, part: str | None, entry: Block, segment: str, out_file: Path) -> SourceInfo:
    from ..sources import hdf5

    dataset = hdf5.dataset_path(part or "/")
    try:
        plan = hdf5.compile_source(key, {"hdf5": str(file), "dataset": dataset}, _document(out_file), file.parent)
    except UserError as exc:
        raise UserError(f"--source {text}: {exc.message}" + ("; name it with hdf5:FILE#/DATASET" if part is None else "")) from None
    entry.add("dataset", dataset)
    info = SourceInfo("hdf5", entry, None, len(plan.names), segment)
    info.notes.append("index: /DATASET  (optional: a 1-D dataset of times or frame numbers; default a row_index sequence)")
    return info


def _rrd(text: str, key: str, file: Path, part: str | None, entry: Block, segment: str, out_file: Path) -> SourceInfo:
    from ..sources import rrd

    if part is None:
        raise UserError(
            f"--source {text}: name the entity holding the values with rrd:FILE#ENTITY, e.g. rrd:{file.name}#/observation.state"
        )
    entry.add("entity", rrd.entity_path(part))
    try:
        plan = rrd.compile_source(key, {"rrd": str(file), "entity": part}, _document(out_file), file.parent)
    except UserError as exc:
        raise _reraise(text, exc) from None
    return SourceInfo("rrd", entry, list(plan.names), None, segment)


def stub_source(key: str, joints: list[str]) -> SourceInfo:
    entry = Block()
    entry.add("parquet", f"{STUB_SOURCE_DIR}/{key}.parquet", "TODO: your data: one row per frame (or another source kind)")
    entry.add("column", "observation.state", "TODO: the list<float> column holding one value per name")
    entry.add("index", "frame_index", "TODO: the timeline column (a sequence); or {timestamp: COL, unit: s}")
    info = SourceInfo("parquet", entry, None, len(joints), "episode_000")
    return info


# ---------------------------------------------------------------------------------------------------------------
# The URDF side: package paths, joint descriptions


def _package_uris(model: UrdfModel) -> dict[str, list[str]]:
    """package NAME -> the rest of each of its mesh URIs, in URDF order."""
    found: dict[str, list[str]] = {}
    for mesh in model.meshes:
        if mesh.uri.startswith("package://"):
            package, _, rest = mesh.uri[len("package://") :].partition("/")
            rests = found.setdefault(package, [])
            if rest not in rests:
                rests.append(rest)
    return found


def _package_candidates(package: str, urdf: Path) -> list[tuple[Path, str]]:
    """Where package NAME may be: an ancestor named NAME, NAME (or share/NAME, NAME/share/NAME) beside an ancestor,
    then ROS_PACKAGE_PATH / AMENT_PREFIX_PATH."""
    chains = []
    for folder in (Path(os.path.abspath(urdf)).parent, Path(os.path.realpath(urdf)).parent):
        chains.append([folder, *folder.parents])
    found: list[tuple[Path, str]] = []
    for chain in chains:
        found += [(a, "an ancestor folder of the URDF") for a in chain if a.name == package]
    for chain in chains:
        for ancestor in chain:
            for candidate in (ancestor / package, ancestor / "share" / package, ancestor / package / "share" / package):
                found.append((candidate, "found beside the URDF"))
    found += [(root, "from ROS_PACKAGE_PATH / AMENT_PREFIX_PATH") for root in package_roots(package)]
    seen: set[str] = set()
    unique = []
    for path, why in found:
        if str(path) not in seen and path.is_dir():
            seen.add(str(path))
            unique.append((path, why))
    return unique


def resolve_package(package: str, rests: list[str], urdf: Path) -> tuple[Path, str, int] | None:
    """The folder holding most of the package's meshes (all, ideally): (folder, why, meshes found there)."""
    best: tuple[Path, str, int] | None = None
    for folder, why in _package_candidates(package, urdf):
        count = sum((folder / unquote(rest)).is_file() for rest in rests)
        if count and (best is None or count > best[2]):
            best = (folder, why, count)
        if count == len(rests):
            break
    return best


def joint_summary(joint: Joint) -> str:
    unit = "rad" if joint.angular else "m"
    if joint.type == "continuous":
        return "continuous, no limits (rad)"
    if joint.has_limits:
        return f"{joint.type}, {number(joint.lower or 0.0)} .. {number(joint.upper or 0.0)} {unit}"
    return f"{joint.type}, no usable limits ({unit})"


def hold_value(joint: Joint) -> float:
    """0.0, or the middle of the limits when 0 is outside them."""
    if not joint.has_limits or (joint.lower or 0.0) <= 0.0 <= (joint.upper or 0.0):
        return 0.0
    lower, upper = float(joint.lower or 0.0), float(joint.upper or 0.0)
    middle = round((lower + upper) / 2, 6)
    return middle if lower <= middle <= upper else (lower + upper) / 2


def _identifier(text: str, fallback: str) -> str:
    cleaned = re.sub(r"[^A-Za-z0-9_-]+", "_", text).strip("_")
    if not cleaned:
        return fallback
    return cleaned if IDENTIFIER.match(cleaned) else f"_{cleaned}"


# ---------------------------------------------------------------------------------------------------------------
# The config


def schema_reference(out_dir: Path) -> str:
    """Relative path to the nearest schemas/urdf-pipeline.schema.json above the output, else the installed schema."""
    real = Path(os.path.realpath(out_dir))
    for folder in (real, *real.parents):
        if (folder / SCHEMA_IN_REPO).is_file():
            return Path(os.path.relpath(folder / SCHEMA_IN_REPO, real)).as_posix()
    installed = resources.files("urdf_pipeline").joinpath("data", SCHEMA_RESOURCE)
    return Path(str(installed)).resolve().as_posix()


@dataclass
class Scaffold:
    text: str
    data: dict[str, Any]
    mapped: int
    by_name: int
    held: int
    ignored: int
    todos: int


def _load(urdf: Path) -> UrdfModel:
    if urdf.name.endswith(".xacro"):
        raise UserError(
            f"{urdf} is a xacro file: init reads a plain URDF (expand it with xacro first, then use the xacro form in the config)"
        )
    if not urdf.is_file():
        raise UserError(f"URDF file not found: {urdf}")
    try:
        _, model = read_urdf(urdf)
    except (UrdfParseError, OSError, UnicodeDecodeError) as exc:
        raise UserError(f"{urdf}: {exc}") from None
    if not any(j.moving and j.mimic is None for j in model.joints):
        raise UserError(
            f"URDF '{model.name}' has no joint to drive (no revolute, continuous or prismatic joint without <mimic>); "
            "a scene URDF goes beside a robot in that robot's config, as a robot without joints"
        )
    return model


def _pair(info: SourceInfo, joint_names: list[str]) -> tuple[list[str], list[Match]]:
    """The source's names and their pre-matched joints. Positional sources (no names) are named after the joints, in
    URDF order (extra values `value_K`); named ones are matched by name, or by position (score 0) if nothing resembles."""
    if info.names is None:
        width = info.width if info.width is not None else len(joint_names)
        names = [joint_names[i] if i < len(joint_names) else f"value_{i}" for i in range(width)]
        return names, [Match(joint_names[i], joint_names[i], 1.0) for i in range(min(width, len(joint_names)))]
    names = list(info.names)
    matches = match_names(names, joint_names)
    if info.kind == "mcap":  # names in any order per message: the map follows the URDF's order
        matches.sort(key=lambda m: joint_names.index(m.joint))
    if not matches:  # the map may not be empty; every entry says it is a guess by position
        matches = [Match(names[i], joint_names[i], 0.0) for i in range(min(len(names), len(joint_names)))]
    return names, matches


def _source_entry(info: SourceInfo, names: list[str], stub: bool) -> Block:
    entry = info.entry
    if info.names is None:
        why = {
            "parquet": "parquet carries no names",
            "hdf5": "HDF5 carries no names",
            "lerobot": "the feature has no names in meta/info.json",
        }[info.kind]
        if stub:
            comment = "the URDF's joints; TODO: the names of your values, in their order (then map each below)"
        elif info.width is None:
            comment = f"review: {why} and the column's width is not fixed: assumed one value per URDF joint, in URDF order"
        else:
            comment = f"review: {why}: assumed the values come in the URDF's joint order"
        entry.add("names", names, comment)
    for note in info.notes:
        entry.note(note)
    return entry


def _package_paths(model: UrdfModel, urdf: Path, out_dir: Path) -> Block | None:
    packages = _package_uris(model)
    if not packages:
        return None
    paths = Block()
    for package, rests in sorted(packages.items()):
        resolved = resolve_package(package, rests, urdf)
        if resolved is None:
            paths.add(package, f"TODO/{package}", f"TODO: the folder package://{package}/... refers to ({len(rests)} mesh files)")
        else:
            folder, why, count = resolved
            comment = why if count == len(rests) else f"review: only {count} of its {len(rests)} mesh files are there"
            paths.add(package, _relative(folder, out_dir), comment)
    return paths


def _joints(model: UrdfModel, source_key: str, info: SourceInfo, names: list[str], matches: list[Match], stub: bool) -> Block:
    drivable = [j for j in model.joints if j.moving and j.mimic is None]
    by_name = {j.name: j for j in model.joints}
    joints = Block()
    joints.add("source", source_key)
    unit = "rad" if any(j.angular for j in drivable) else "m"
    other = "prismatic joints say theirs (m | mm) in their entry" if unit == "rad" else "all joints are prismatic"
    joints.add("unit", unit, f"review: the unit of the source values ({'rad | deg' if unit == 'rad' else 'm | mm'}); {other}")
    mapping = Block()
    for match in matches:
        joint = by_name[match.joint]
        value: Any = match.joint if joint.angular == (unit == "rad") else {"joint": match.joint, "unit": "rad" if joint.angular else "m"}
        if stub:
            comment = joint_summary(joint)
        elif info.names is None:
            comment = f"review: matched by position; {joint_summary(joint)}"
        elif match.score == 0.0:
            comment = f"TODO: no source name resembles a joint name: matched by position, surely wrong; {joint_summary(joint)}"
        else:
            comment = f"review: matched by name (score {match.score:.2f}); {joint_summary(joint)}"
        mapping.add(match.source_name, value, comment)
    joints.add("map", mapping, "source name: URDF joint (add sign, offset, unit per entry when needed)")
    matched_sources = {m.source_name for m in matches}
    unmatched = [n for n in names if n not in matched_sources]
    if unmatched:
        why = "a value beyond the URDF's joints" if info.names is None else "no URDF joint resembles it"
        joints.add("ignore", Seq([(n, f"TODO: {why}: map it, or keep it ignored") for n in unmatched]), "source names deliberately unused")
    matched_joints = {m.joint for m in matches}
    held = [j for j in drivable if j.name not in matched_joints]
    if held:
        hold = Block()
        for joint in held:
            value = hold_value(joint)
            hold.add(joint.name, value, f"TODO: not in the data, held at {number(value)}; {joint_summary(joint)}")
        joints.add("hold", hold, "URDF joints the data lacks -> a fixed value in URDF units")
    for joint in model.joints:
        if joint.mimic is not None:
            m = joint.mimic
            joints.note(
                f"mimic (computed by the pipeline, not mapped): {joint.name} = {m.joint} * {number(m.multiplier)} + {number(m.offset)}"
            )
    for joint in model.joints:
        if joint.type in ("floating", "planar"):
            joints.note(
                f"{joint.type} joint {joint.name} ({joint.parent} -> {joint.child}) is not driven: a static identity unless "
                "a temporal edge (edges: - {parent, child, source, translation, quaternion_xyzw}) drives it"
            )
    return joints


def scaffold(urdf: Path, source: str | None, out_file: Path) -> Scaffold:
    """The config text for URDF `urdf` (and source spec `source`), to be written at `out_file` (paths relative to it)."""
    model = _load(urdf)
    out_dir = out_file.parent
    key = _identifier(model.name, _identifier(urdf.stem.split(".")[0], "robot"))
    source_key = f"{key}_state"
    joint_names = [j.name for j in model.joints if j.moving and j.mimic is None]
    stub = source is None
    info = stub_source(key, joint_names) if source is None else read_source(source, source_key, out_file)
    names, matches = _pair(info, joint_names)
    if not matches:
        raise UserError(f"--source {source}: it holds no values")

    sources = Block()
    sources.add(
        source_key, _source_entry(info, names, stub), "TODO: where the joint values come from" if stub else f"from --source {source}"
    )
    robot = Block()
    robot.add("urdf", _relative(urdf, out_dir), f"{model.name}: {len(joint_names)} joints to drive, {len(model.links)} links")
    paths = _package_paths(model, urdf, out_dir)
    if paths is not None:
        stubbed = any("TODO" in i.comment for i in paths.items if isinstance(i, Item))
        robot.add("package_paths", paths, "TODO: meshes that do not resolve until the stubs below are filled in" if stubbed else "")
    joints = _joints(model, source_key, info, names, matches, stub)
    robot.add("joints", joints)
    robots = Block()
    robots.add(key, robot)

    root = "world" if "world" not in model.links or model.root_link == "world" else "scene"  # a URDF link 'world' below its root
    frames = Block()
    frames.add("root", root, "the one root frame of the scene")
    config = Block()
    config.add("version", 1)
    config.add("sources", sources)
    config.add("robots", robots)
    config.add("frames", frames)
    if model.root_link != root:
        edge = Block()
        edge.add("parent", root)
        edge.add("child", model.root_link, "the URDF's root link")
        edge.add("translation", [0.0, 0.0, 0.0], "TODO: measure (m)")
        edge.add("quaternion_xyzw", [0.0, 0.0, 0.0, 1.0], "TODO: measure (or rpy / rpy_deg)")
        config.add("edges", Seq([(edge, "")]), "calibration: where the robot stands in the scene")
    else:
        frames.note(f"the URDF's root link is '{root}' itself: no calibration edge needed")
    output = Block()
    output.add("path", "out/{segment}.rrd")
    output.add("application_id", key)
    output.add("segment", info.segment, "the recording id (layers attach only when it equals the base recording's)")
    config.add("output", output)

    header = [
        f"# yaml-language-server: $schema={schema_reference(out_dir)}",
        f"# Generated by `urdf-pipeline init` from {_relative(urdf, out_dir)}" + (f" and {source}." if source else "."),
        "# `TODO:` marks what init could not know (a stub to fill in, a decision to make); `review:` a guess to check.",
        "# Then `urdf-pipeline check` compares the data with the URDF limits and suggests unit and sign corrections.",
    ]
    body = render_block(config)
    data = to_data(config)
    return Scaffold(
        text="\n".join(header + body) + "\n",
        data=data,
        mapped=len(matches),
        by_name=0 if stub or info.names is None else sum(m.score > 0 for m in matches),
        held=len(data["robots"][key]["joints"].get("hold", {})),
        ignored=len(data["robots"][key]["joints"].get("ignore", [])),
        todos=sum("# TODO" in line for line in body),
    )


def self_check(result: Scaffold, out_file: Path) -> Document:
    """The text must read back as the intended data and satisfy the schema: anything else is a bug of init's."""
    from ..config.schema import validate_document

    document = parse_document(result.text, out_file)
    if yaml.safe_load(result.text) != result.data:
        raise AssertionError("init: the generated YAML does not read back as intended:\n" + result.text)
    try:
        validate_document(document)
    except UserError as exc:
        raise AssertionError("init: the generated config fails the schema: " + "; ".join(exc.lines())) from None
    return document


def remaining_problems(document: Document) -> list[str]:
    """What `validate` would still refuse (expected: the TODO stubs), as messages without the file location."""
    from ..compile.compiler import compile_document
    from ..errors import UserErrors

    try:
        compile_document(document)
    except UserErrors as exc:
        return [f"{e.where.path}: {e.message}" if e.where and e.where.path else e.message for e in exc.errors]
    except UserError as exc:
        return [f"{exc.where.path}: {exc.message}" if exc.where and exc.where.path else exc.message]
    return []


def init_config(urdf: Path, source: str | None, output: Path | None, force: bool) -> tuple[Scaffold, list[str]]:
    """Scaffold, check and write (to `output`, or return it for stdout); the lines to say on stderr."""
    out_file = (output if output is not None else Path.cwd() / "urdf-pipeline.yaml").absolute()
    if output is not None and out_file.exists() and not force:
        raise UserError(f"{output} exists; --force overwrites it")
    result = scaffold(urdf, source, out_file)
    problems = remaining_problems(self_check(result, out_file))
    if output is not None:
        out_file.parent.mkdir(parents=True, exist_ok=True)
        partial = out_file.with_name(out_file.name + ".partial")
        partial.write_text(result.text, encoding="utf-8")
        partial.replace(out_file)
    how = f"{result.by_name} by name, for review" if result.by_name else "by position" if source else "the stub's names"
    said = [
        f"init: {result.mapped} joint(s) mapped ({how}), {result.held} held, {result.ignored} source name(s) ignored; "
        f"{result.todos} TODO(s) to settle" + (f" in {output}" if output is not None else "")
    ]
    if problems:
        said.append(f"init: validate would still refuse {len(problems)} thing(s), the stubs marked TODO:")
        said += [f"  {problem}" for problem in problems]
    else:
        said.append("init: the config validates; review the guesses marked `review:` and `TODO:`")
    return result, said
