"""What init says on stderr (worded here only), and what the written config still lacks: `validate`'s refusals and
check's refusals of a sample (init_units.py). "the config validates" only when both accept it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..config import Document
from ..errors import UserError, UserErrors
from ..plan import Plan


@dataclass(frozen=True)
class Scaffold:
    """The config text and what it holds, counted for the summary init prints."""

    text: str
    data: dict[str, Any]  # what the text reads back as
    stub: bool  # no --source: the stub source
    mapped: int
    by_name: int
    held: int
    ignored: int
    todos: int
    mismatch: str = ""  # a positional source whose width is not the URDF's joints to drive: what differs, what to edit


def compiled(document: Document) -> tuple[Plan | None, list[str]]:
    """The plan, or what `validate` would refuse (as messages without the file location)."""
    from ..compile import compile_document

    try:
        return compile_document(document), []
    except UserError as exc:
        errors = exc.errors if isinstance(exc, UserErrors) else [exc]
        return None, [f"{e.where.path}: {e.message}" if e.where and e.where.path else e.message for e in errors]


@dataclass(frozen=True)
class SampleVerdict:
    """What init's sample says of the written config: check's refusals, or why there was no sample."""

    refused: tuple[str, ...] = ()
    unread: str = ""  # the sample could not be read: why
    rows: int = 0


def summary_lines(result: Scaffold, problems: list[str], output: Path | None, sample: SampleVerdict | None = None) -> list[str]:
    """What init says on stderr, from its result, what validate would still refuse and what check says of the
    sample: worded here only. "the config validates" only when validate accepts it and check's rules accept its sample."""
    how = f"{result.by_name} by name, for review" if result.by_name else "the stub's names" if result.stub else "by position"
    said = [
        f"init: {result.mapped} joint(s) mapped ({how}), {result.held} held, {result.ignored} source name(s) ignored; "
        f"{result.todos} TODO(s) to settle" + (f" in {output}" if output is not None else "")
    ]
    if output is None:
        said.append(
            f"init: the paths in the printed config are relative to the current folder ({Path.cwd()}): save it there, "
            "or use -o FILE to have them written relative to FILE's folder"
        )
    if result.mismatch:
        said.append("init: the source's width differs from the URDF's joints to drive, so its names are a guess to settle:")
        said.append(f"  {result.mismatch}")
    refused = sample.refused if sample is not None else ()
    if problems:
        said.append(f"init: validate would still refuse {len(problems)} thing(s), the stubs marked TODO:")
        said += [f"  {problem}" for problem in problems]
    elif refused:
        said.append(
            f"init: validate accepts it, but {len(refused)} mapped value(s) of the sample ({sample.rows if sample else 0} rows) "
            "do not fit their URDF limits as written, so a run would stop; look at these entries (`urdf-pipeline check` says more):"
        )
        said += [f"  {line}" for line in refused]
    elif result.mismatch:
        said.append("init: validate accepts it as written, but its names stay a guess by position until that is settled")
    elif sample is not None and sample.unread:
        said.append(f"init: validate accepts it, but no sample of the source could be read ({sample.unread}): run `urdf-pipeline check`")
    else:
        said.append("init: the config validates; review the guesses marked `review:` and `TODO:`")
    return said
