"""Where a run writes: each segment's recording (`output.path`), the split layout's model, the manifest and the
blueprint beside it, each checked against the write rule (confine.py) or, for `s3://` outputs (docs/remote.md: one
bucket, staged here then uploaded), the allow rule for URLs."""

from __future__ import annotations

import itertools
from pathlib import Path

from ..config import Placeholder, checked_template
from ..confine import resolved_or_written
from ..errors import UserError, quoted, shown
from ..plan import DatasetPlan, RemoteOutputs, Segment
from ..remote import is_remote, remote_location, staged_path, staging_folder
from .context import CompileContext

OUTPUT_PATH = {"segment": Placeholder(str)}  # output.path's placeholders


def output_paths(ctx: CompileContext, template: str, ids: list[str]) -> list[Path] | None:
    problems = ctx.problems
    where = ctx.where("output", "path")
    try:
        checked = checked_template(template, OUTPUT_PATH, "output.path", where)
    except UserError as error:
        problems.extend(error)
        return None
    if len(ids) > 1 and "segment" not in checked.fields:
        problems.add(f"{len(ids)} segments would all be written to {quoted(template)}; put {{segment}} in output.path", where)
        return None
    try:
        return [_place(ctx, checked.format(segment=i), "path") for i in ids]
    except UserError as error:
        problems.extend(error)
        return None


def dataset_plan(ctx: CompileContext, segments: tuple[Segment, ...]) -> DatasetPlan | None:
    problems, output, config_dir = ctx.problems, ctx.data["output"], ctx.config_dir
    remote = _remote_outputs(ctx)
    if remote is False:
        return None
    layout = output.get("layout", "single")
    model: Path | None = None
    if layout == "split":
        if "model" not in output:
            problems.add(
                "layout: split writes the robot model once: give its path in output.model (e.g. out/model.rrd)",
                ctx.where("output", "layout"),
            )
            return None
        if "{" in output["model"]:
            problems.add("output.model is written once for all segments: it takes no placeholder", ctx.where("output", "model"))
            return None
        model = _place(ctx, output["model"], "model")
        if any(s.output == model for s in segments):
            problems.add(f"output.model {shown(output['model'])} is also a segment's output path", ctx.where("output", "model"))
            return None
    elif "model" in output:
        problems.add("output.model is only used with layout: split; remove it or set layout: split", ctx.where("output", "model"))
        return None
    if "manifest" in output:
        manifest = _place(ctx, output["manifest"], "manifest")
    else:
        directory = _fixed_directory(output["path"], config_dir)
        manifest = directory / f"{ctx.document.file.stem}.manifest.json"
    if remote is None and not _outputs_confined(ctx, segments, model, manifest):
        return None
    joint_series = bool(output.get("joint_series", False))
    remote_outputs = remote if isinstance(remote, RemoteOutputs) else None
    return DatasetPlan(layout, segments, model, manifest, ctx.where("output", "segment"), joint_series, remote_outputs)


def _place(ctx: CompileContext, text: str, key: str) -> Path:
    """A single output's path: its staged path for a URL (same bucket as output.path: `_remote_outputs` checked)."""
    if is_remote(text):
        return staged_path(remote_location(text, ctx.where("output", key), f"output.{key}"))
    return resolved_or_written(ctx.config_dir / text)


def _remote_outputs(ctx: CompileContext) -> RemoteOutputs | None | bool:
    """The bucket the outputs go to (None: local files), or False (problems added) when they are not all in one:
    recordings, model and manifest are listed, compared and uploaded together."""
    output = ctx.data["output"]
    keys = [key for key in ("path", "model", "manifest") if key in output]
    remote = [key for key in keys if is_remote(output[key])]
    if not remote:
        return None
    if remote != keys:
        local = [key for key in keys if key not in remote]
        ctx.problems.add(
            f"output.{remote[0]} is a URL but output.{local[0]} is a local path: a run's outputs go together, all "
            "to one bucket or all to local files",
            ctx.where("output", local[0]),
        )
        return False
    try:
        locations = {key: remote_location(output[key], ctx.where("output", key), f"output.{key}") for key in keys}
    except UserError as error:
        ctx.problems.extend(error)
        return False
    buckets = {location.bucket for location in locations.values()}
    if any(location.scheme != "s3" for location in locations.values()) or len(buckets) != 1:
        ctx.problems.add(
            "outputs are written to one S3 bucket (s3://BUCKET/...): the Hub is read, not written", ctx.where("output", "path")
        )
        return False
    bucket = buckets.pop()
    return RemoteOutputs(staging_folder(bucket), f"s3://{bucket}/")


def _outputs_confined(ctx: CompileContext, segments: tuple[Segment, ...], model: Path | None, manifest: Path) -> bool:
    """Every file a run writes (recordings, model, manifest, the blueprint beside it) obeys confine.py's write rule."""
    confinement = ctx.confinement
    blueprint = manifest.parent / f"{ctx.document.file.stem}.rbl"
    writes = [(s.output, "the recording", ("output", "path")) for s in segments]
    writes += [(model, "the model", ("output", "model"))] if model is not None else []
    manifest_key = ("output", "manifest") if "manifest" in ctx.data["output"] else ("output", "path")
    writes += [(manifest, "the manifest", manifest_key), (blueprint, "the blueprint", manifest_key)]
    refused: set[tuple[str, ...]] = set()
    for path, what, key in writes:
        if key in refused:
            continue  # one error per key: every segment of a template outside the folder is outside
        try:  # the rule, then what is on disk: a folder in the way, a name too long, a symlink loop
            confinement.check_write(path, what, ctx.where(*key))
        except UserError as error:
            refused.add(key)
            ctx.problems.extend(error)
    return not refused


def _fixed_directory(template: str, base: Path) -> Path:
    """The deepest directory of output.path before any placeholder: where the manifest goes by default."""
    if is_remote(template):  # s3://BUCKET/a/b/{segment}.rrd: the staged folder of s3://BUCKET/a/b/
        head = template.split("{", 1)[0].rsplit("/", 1)[0]
        return staged_path(remote_location(head + "/x", None, "output.path")).parent
    fixed = itertools.takewhile(lambda part: "{" not in part, Path(template).parent.parts)
    return resolved_or_written(base.joinpath(*fixed))
