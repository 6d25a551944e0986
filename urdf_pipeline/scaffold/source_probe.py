"""init's view of a source: SOURCE_SPEC -> the kind's description (`sources`' `describe`, from metadata only, as
validate reads it), with its path as the config will say it; and the stub source when there is no SOURCE_SPEC."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from ..config import Document
from ..confine import is_remote
from ..errors import UserError, shown
from ..sources import GLOB, KINDS, EntryField, SourceDescription, kind_for_path

STUB_SOURCE_DIR = "TODO"  # the stub parquet path starts here: it does not exist, so validate fails on it alone


@dataclass(frozen=True)
class SourceInfo:
    """A source as init writes it: the kind's description and its path, relative to the config's folder."""

    description: SourceDescription
    path: str  # the value of the kind's key in the config entry
    path_comment: str = ""


def parse_source_spec(text: str) -> tuple[str, str, str | None]:
    """`KIND:PATH[#PART]` -> (kind, path, part); KIND inferred from PATH when left out."""
    kind, sep, rest = text.partition(":")
    if not sep or kind not in KINDS:
        kind, rest = "", text
    path, hash_, part = rest.partition("#")
    if is_remote(path):  # init reads a sample of the data: a local copy of it
        raise UserError(
            f"--source {shown(text)}: init reads a local file or dataset (a sample of its values); download one, run init "
            "on it, then put the s3:// or hf:// location in the config it writes"
        )
    if not path:
        raise UserError(f"--source '{text}': no path; the form is KIND:PATH[#PART], KIND one of {', '.join(KINDS)}")
    if not kind:
        found = kind_for_path(path)
        if found is None:
            forms = [module.SPEC_FORM for module in KINDS.values()]
            raise UserError(f"--source '{text}': say which kind of source it is: {', '.join(forms[:-1])} or {forms[-1]}")
        kind = found
    return kind, path, (part or None) if hash_ else None


def relative_to(target: str | Path, base: Path) -> str:
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
    return f"{relative_to(folder or '.', base)}/{name}".removeprefix("./")


def read_source(text: str, key: str, out_file: Path) -> SourceInfo:
    """The source SOURCE_SPEC `text` names, described by its kind, for a config written at `out_file`."""
    kind, path, part = parse_source_spec(text)
    try:  # the config does not exist yet: a problem is the --source argument's, not at a place in a file
        described = KINDS[kind].describe(key, path, part, Document(out_file, {}, {}))
    except UserError as exc:
        raise UserError(f"--source {text}: {exc.message}") from None
    base = out_file.parent
    return SourceInfo(described, _relative_pattern(path, base) if described.pattern else relative_to(path, base))


def stub_source(key: str, joints: list[str]) -> SourceInfo:
    """A parquet source that does not exist yet, named after the joints: validate fails on its file alone."""
    fields = (
        EntryField("column", "observation.state", "TODO: the list<float> column holding one value per name"),
        EntryField("index", "frame_index", "TODO: the timeline column (a sequence); or {timestamp: COL, unit: s}"),
    )
    described = SourceDescription("parquet", fields, None, len(joints), "episode_000", unnamed="parquet carries no names")
    return SourceInfo(described, f"{STUB_SOURCE_DIR}/{key}.parquet", "TODO: your data: one row per frame (or another source kind)")
