"""The one checker of format templates from input (config/templates.py): what LeRobot and configs write is accepted,
every door str.format opens is refused with a reason, and an accepted template formats within its bound whatever
value of its kind it is given."""

from __future__ import annotations

from pathlib import Path

import pytest

from urdf_pipeline.config import Placeholder, checked_template
from urdf_pipeline.config.templates import MAX_WIDTH, TemplateError, parse_template
from urdf_pipeline.errors import UserError, Where
from urdf_pipeline.sources.lerobot_meta import V2_PLACEHOLDERS, V3_PLACEHOLDERS, VIDEO_KEY

SEGMENT = {"episode": Placeholder(int), "stem": Placeholder(str)}


@pytest.mark.parametrize(
    "text",
    ["episode_{episode:06d}", "{stem}", "{episode:08d}_{stem:>20}", "{episode:x}", "{stem:.40}", "{{literal}}_{episode}", "plain", ""],
)
def test_what_configs_write_is_accepted(text: str) -> None:
    assert parse_template(text, SEGMENT).text == text


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("{epsiode}", "has the unknown placeholder '{epsiode}'; known: {episode}, {stem}"),
        ("{}", "has a positional placeholder '{}'"),
        ("{0}", "has a positional placeholder '{0}'"),
        ("{episode.__class__}", "reads an attribute or item in '{episode.__class__}'"),
        ("{stem[0]}", "reads an attribute or item in '{stem[0]}'"),
        ("{episode!r}", "converts '{episode!r}'; remove !r"),
        ("{stem!a}", "converts '{stem!a}'"),
        ("{episode:999999999d}", f"asks for a width of 999999999 in {{episode}}; at most {MAX_WIDTH}"),
        ("{stem:.99999}", "asks for a precision of 99999 in {stem}"),
        ("{stem:" + "9" * 5000 + "}", "asks for a width of 999999999999…"),
        ("{episode:{stem}}", "nests a placeholder in the format spec of {episode}"),
        ("{stem:d}", "has the format spec 'd' in {stem}, not one for text"),
        ("{episode:s}", "has the format spec 's' in {episode}, not one for a number"),
        ("{episode:c}", "not one for a number"),  # chr() of a large index raises OverflowError
        ("{episode:.3d}", "wrong for a number (Precision not allowed in integer format specifier)"),
        ("{stem:=5}", "wrong for text"),
        ("{episode:/>9}", "not one for a number"),  # a fill character: '/' or '.' would make path parts
        ("{episode", "is not a format template"),
        ("}", "is not a format template"),
    ],
)
def test_every_door_of_str_format_is_refused(text: str, says: str) -> None:
    with pytest.raises(TemplateError) as refused:
        parse_template(text, SEGMENT)
    assert says in str(refused.value)


def test_a_refusal_is_located_and_names_the_key() -> None:
    where = Where(Path("c.yaml"), 7, "output.segment", 3)
    with pytest.raises(UserError) as refused:
        checked_template("ep_{episode:999999999d}", SEGMENT, "output.segment", where)
    assert refused.value.where == where
    assert refused.value.message.startswith("output.segment 'ep_{episode:999999999d}' asks for a width")


@pytest.mark.parametrize("spec", ["", "06d", f"{MAX_WIDTH}d", f">{MAX_WIDTH}", f"0{MAX_WIDTH}x", f"#0{MAX_WIDTH}b", f"0{MAX_WIDTH}_d"])
def test_an_accepted_template_formats_within_its_bound(spec: str) -> None:
    template = parse_template("{episode:" + spec + "}" if spec else "{episode}", SEGMENT)
    for value in (0, 2**63 - 1):
        assert len(template.format(episode=value)) <= max(MAX_WIDTH, 2 + 63 + 21)  # the width, or a prefix, 63 bits, separators


def test_lerobot_templates_are_taken_only_as_rerun_s_reader_substitutes_them() -> None:
    assert parse_template("data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet", V2_PLACEHOLDERS).fields == {
        "episode_chunk",
        "episode_index",
    }
    assert parse_template("data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet", V3_PLACEHOLDERS).fields == {
        "chunk_index",
        "file_index",
    }
    video = {**V2_PLACEHOLDERS, **VIDEO_KEY}
    assert parse_template("videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4", video).fields == {
        "episode_chunk",
        "video_key",
        "episode_index",
    }
    for text in ("data/{episode_index}.parquet", "data/{episode_index:08d}.parquet", "data/{chunk_index:03d}.parquet", "{video_key:>3}"):
        with pytest.raises(TemplateError):
            parse_template(text, video)
