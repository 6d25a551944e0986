"""Review text a pull request cannot forge: names from a stranger's config, URDF and file names reach no output line
raw. No line of any format starts a GitHub workflow command, control characters are shown escaped, `github` escapes
as the runner reads it, Markdown shows PR content as inert text, and no line grows with the input."""

from __future__ import annotations

import json
import logging
import os
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.dataset.run_report import summary_table
from urdf_pipeline.errors import LINE_LIMIT, Where, escaped, listing, located, neutral_line, neutral_text, quoted, shown
from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.execute import SegmentResult
from urdf_pipeline.logs import LOGGER, command_logging
from urdf_pipeline.review.markdown_text import cell, code, plain
from urdf_pipeline.review.validate.annotations import Annotation

# Names an attacker would try: Markdown and HTML that breaks out of a PR comment, workflow commands, a newline and a
# CR (the runner reads a CR as a line end too), a direction override, a mention.
HOSTILE = [
    "</details><!--",
    "`` ` ``",
    "[x](http://evil)",
    "![i](http://evil/i.png)",
    "# h",
    "a|b",
    "a\\|b",
    "::error::x",
    "  ::warning file=a,line=1::w",
    "##[error]old",
    "line\nbreak",
    "cr\r::error::cr",
    "bidi\u202etxt",
    "@here <b>&amp; *em* _u_ ~s~ $x$",
]
CONTROL = re.compile("[\x00-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]")
BOUND = 2_000  # characters of any output line, whatever the input holds


def _xml(text: str) -> str:
    """An XML attribute value holding `text` (newline and CR as character references, as a URDF can)."""
    for char, entity in (("&", "&amp;"), ("<", "&lt;"), (">", "&gt;"), ('"', "&quot;"), ("\n", "&#10;"), ("\r", "&#13;")):
        text = text.replace(char, entity)
    return text


def _urdf(links: list[str], moving: str = "shoulder", robot: str = "::error::rob\nx") -> str:
    parts = ['<link name="base"/><link name="arm"/>', *(f'<link name="{_xml(n)}"/>' for n in links)]
    parts.append(
        f'<joint name="{_xml(moving)}" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>'
        '<limit lower="-2" upper="2" effort="1" velocity="1"/></joint>'
    )
    parts += [
        f'<joint name="{_xml(n)}_j{i}" type="fixed"><parent link="arm"/><child link="{_xml(n)}"/></joint>' for i, n in enumerate(links)
    ]
    return f'<?xml version="1.0"?>\n<robot name="{_xml(robot)}">{"".join(parts)}</robot>\n'


def _workspace(folder: Path, links: list[str], moving: str, source_name: str, stems: list[str], map_to: str | None = None) -> Path:
    """A config whose robot's links, joints, source value and globbed files carry the given names."""
    (folder / "robots").mkdir(parents=True, exist_ok=True)
    (folder / "robots" / "h.urdf").write_text(_urdf(links, moving), encoding="utf-8")
    for stem in stems:
        write_joint_parquet(folder / "data" / f"{stem}.parquet", np.zeros((5, 1)))
    config = {
        "version": 1,
        "sources": {"src": {"parquet": "data/*.parquet", "column": "observation.state", "index": "frame_index", "names": [source_name]}},
        "robots": {"rig": {"urdf": "robots/h.urdf", "joints": {"source": "src", "map": {source_name: map_to or moving}}}},
        "frames": {"root": "base"},
        "output": {"path": "out/{segment}.rrd", "application_id": "h", "segment": "{stem}"},
    }
    path = folder / "c.yaml"
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    return path


@pytest.fixture
def hostile(tmp_path: Path) -> Path:
    return _workspace(tmp_path / "h", HOSTILE, "::error::shoulder\n::warning::j", "::error::q\n#x", ["::error::ep", "ep`x`<!--"])


def _assert_neutral(text: str, bound: int = BOUND, control: bool = True, github: bool = False) -> None:
    """No line a workflow command (after the whitespace the runner trims), none unbounded, no control character.
    `github`: every line is one of the tool's own annotations, as the runner reads it."""
    for line in filter(None, text.split("\n")) if github else text.split("\n"):
        if github:
            command, properties, _ = _runner_parse(line)
            assert command in ("error", "warning", "notice") and set(properties) <= {"file", "line", "col"}, line
        else:
            assert not line.lstrip().startswith(("::", "##[")), line
        assert len(line) <= bound, len(line)
        if control:
            assert not CONTROL.search(line), line


def _outside_code(line: str) -> str:
    """The line with its code spans removed (a backtick run closes at the next run of the same length)."""
    out, at = [], 0
    while (start := line.find("`", at)) >= 0:
        run = len(line[start:]) - len(line[start:].lstrip("`"))
        end = line.find("`" * run, start + run)
        while end >= 0 and (line[end + run : end + run + 1] == "`" or line[end - 1 : end] == "`"):
            end = line.find("`" * run, end + 1)
        out.append(line[at:start])
        if end < 0:
            return "".join(out) + line[start:]
        at = end + run
    return "".join(out) + line[at:]


def _cells(row: str) -> int:
    """Cell borders GitHub sees in a table row: `|` not escaped by a backslash."""
    count, escaped_next = 0, False
    for char in row:
        if escaped_next:
            escaped_next = False
        elif char == "\\":
            escaped_next = True
        elif char == "|":
            count += 1
    return count


def _assert_inert_markdown(markdown: str) -> None:
    _assert_neutral(markdown)
    header_cells = 0
    fenced = False
    for line in markdown.split("\n"):
        if line.startswith("```"):
            fenced = not fenced
            continue
        if fenced:  # the mermaid block: its own escaping (#lt; ...), and no backtick can end the fence
            assert "`" not in line, line
            continue
        if line.startswith("#"):
            assert line.startswith(("### urdf-pipeline plan: ", "#### ")), line
        if line.startswith("| "):
            header_cells = header_cells if line.startswith("| ---") or header_cells and not line.startswith("| source |") else 0
            cells = _cells(line)
            header_cells = header_cells or cells
            assert cells == header_cells, line
        else:
            header_cells = 0
        plain_part = _outside_code(line).removeprefix("**urdf-pipeline diff**")  # the tool's own bold title
        assert "<" not in plain_part and ">" not in plain_part.replace("> Per source value", ""), line  # no HTML, <!--, </details>
        assert not re.search(r"(?<!\\)(?:\\\\)*[\[\]*~$]", plain_part), line  # no link, image, emphasis or math
    assert not fenced


# ------------------------------------------------------------------------------------------------ the helpers


def test_shown_escapes_every_control_character_and_shortens_with_the_length() -> None:
    assert shown("a\nb\r\t\x1b[31m\x00\x7f\x85\u202e\u2066\u2028\ufeff\udcff") == (
        "a\\nb\\r\\t\\x1b[31m\\x00\\x7f\\x85\\u202e\\u2066\\u2028\\ufeff\\udcff"
    )
    assert shown("plain_name/with spaces") == "plain_name/with spaces"
    long = shown("a" * 5_000)
    assert long.endswith("a (5,000 characters)") and "…" in long and len(long) <= 200
    assert quoted("a" * 5_000).endswith("a' (5,000 characters)") and quoted("j1") == "'j1'"
    assert escaped("back\\slash") == "back\\slash"  # backslashes stay: `\n` in a name reads as written


@pytest.mark.parametrize("line", ["::error::x", "  ::add-mask::s", "\t::stop-commands::t", "\u3000::notice::n", "##[error]e", "::"])
def test_a_line_that_would_be_a_workflow_command_gets_a_backslash(line: str) -> None:
    assert neutral_line(line).startswith("\\") and not neutral_line(line).lstrip().startswith("::")


def test_neutral_text_keeps_its_lines_and_guards_each() -> None:
    assert neutral_text("ok\n::error::x\ncr\r::warning::y\n") == "ok\n\\::error::x\ncr\\r::warning::y\n"
    assert neutral_text("") == "" and neutral_text("a") == "a"
    assert len(neutral_line("x" * 10**6)) <= LINE_LIMIT


def test_located_is_one_bounded_line_whatever_the_file_path_and_message_hold() -> None:
    where = Where(Path("f\n::warning::x.yaml"), 3, "robots.a\r\n::error::b", 2)
    line = located("error", "joint '::x\n::error::bad' \x1b[2J", where)
    assert line == "error: f\\n::warning::x.yaml:3:2: robots.a\\r\\n::error::b: joint '::x\\n::error::bad' \\x1b[2J"
    huge = located("error", "m" * 10**6, Where(Path("p" * 10**5), 1, "k" * 10**6, 1))
    assert "\n" not in huge and len(huge) <= LINE_LIMIT and huge.startswith("error: ppp")


def test_listing_bounds_each_name_and_the_count() -> None:
    names = ["x" * 10**6, "::error::a\nb", *(f"n{i}" for i in range(100_000))]
    text = listing(names)
    assert len(text) < 1_000 and "\n" not in text and text.endswith("and 99,990 more") and "(1,000,000 characters)" in text


# ------------------------------------------------------------------------------------------------ github format


def _runner_parse(line: str) -> tuple[str, dict[str, str], str]:
    """A workflow command read as the GitHub Actions runner reads one (ActionCommand.TryParseV2, unescaping)."""
    assert line.startswith("::")
    end = line.index("::", 2)
    info, data = line[2:end], line[end + 2 :]
    command, _, props = info.partition(" ")
    properties = {}
    for pair in filter(None, props.split(",")):
        key, _, value = pair.partition("=")
        properties[key] = value.replace("%0D", "\r").replace("%0A", "\n").replace("%3A", ":").replace("%2C", ",").replace("%25", "%")
    return command, properties, data.replace("%0D", "\r").replace("%0A", "\n").replace("%25", "%")


@pytest.mark.parametrize("name", [*HOSTILE, "100%,x:y::z", "%0A%25"])
def test_github_escapes_data_and_properties_as_the_runner_reads_them(name: str) -> None:
    annotation = Annotation.at("error", f"no joint {quoted(name)}", Where(Path(f"cfg {name}.yaml"), 4, f"robots.{name}", 2), "c.yaml")
    line = annotation.github()
    assert "\n" not in line and "\r" not in line and line.startswith("::error file=")
    command, properties, data = _runner_parse(line)
    assert command == "error" and set(properties) == {"file", "line", "col"} and (properties["line"], properties["col"]) == ("4", "2")
    assert properties["file"] == shown(os.path.normpath(f"cfg {name}.yaml")) and data == f"robots.{shown(name)}: no joint {quoted(name)}"


def test_github_and_json_annotations_of_a_huge_name_are_bounded() -> None:
    annotation = Annotation.at("warning", "m" * 10**6, Where(Path("f" * 10**5), 1, "k" * 10**6, 1), "c.yaml")
    assert len(annotation.github()) <= BOUND and len(json.dumps(annotation.message)) <= BOUND


# ------------------------------------------------------------------------------------------------ Markdown


@pytest.mark.parametrize("name", [*HOSTILE, "`", "``", " `x` ", "a" * 1000])
def test_a_code_span_holds_any_name(name: str) -> None:
    span = code(name)
    assert _outside_code(span) == "" and "\n" not in span
    fence = len(span) - len(span.lstrip("`"))
    inside = span[fence:-fence]
    assert "`" * fence not in inside  # no run inside as long as the fence
    if inside.strip("`") != inside:  # a backtick at an end is padded, so CommonMark does not read it as the fence
        assert inside.startswith(" ") and inside.endswith(" ")


def test_plain_text_and_cells_escape_markdown_and_html() -> None:
    assert plain("<b>&x</b> [l](u) ![i](s) # * ~ $ \\ frame_index _u_") == (
        "&lt;b&gt;&amp;x&lt;/b&gt; \\[l\\](u) \\!\\[i\\](s) \\# \\* \\~ \\$ \\\\ frame_index \\_u\\_"
    )
    assert cell("a|b") == "a\\|b" and _cells(cell("a\\|b")) == 0 and _cells(cell("a\\\\|b")) == 0


# ------------------------------------------------------------------------------------------------ the commands


def test_plan_shows_hostile_names_inert_in_every_format(run_cli, hostile: Path) -> None:
    for format in ("text", "markdown", "json"):
        result = run_cli("plan", str(hostile), "--format", format)
        assert result.code == 0, result.err
        _assert_neutral(result.err)
        if format == "markdown":
            _assert_inert_markdown(result.out)
            assert "`::error::shoulder\\n::warning::j`" in result.out and "``` `` ` `` ```" in result.out
        elif format == "json":
            _assert_neutral(result.out)
            data = json.loads(result.out)  # json holds the names as they are: JSON's own escaping is enough
            assert data["robots"][0]["joints"][0]["joint"] == "::error::shoulder\n::warning::j"
            assert {s["id"] for s in data["output"]["segments"]} == {"::error::ep", "ep`x`<!--"}
        else:
            _assert_neutral(result.out)
            assert "::error::q\\n#x[0] -> ::error::shoulder\\n::warning::j" in result.out


def test_validate_errors_naming_hostile_names_are_neutral_in_every_format(run_cli, tmp_path: Path) -> None:
    config = _workspace(
        tmp_path, HOSTILE, "::error::shoulder\n::warning::j", "::error::q\n#x", ["ep"], map_to="::warning::no\n::error::z,%:"
    )
    for format in ("text", "github", "json"):
        result = run_cli("validate", str(config), "--format", format)
        assert result.code == 1
        _assert_neutral(result.out, github=format == "github")
        _assert_neutral(result.err)
        shown_text = "".join(a["message"] for a in json.loads(result.out)) if format == "json" else result.out + result.err
        assert "no joint '::warning::no\\n::error::z," in shown_text  # a newline shows as `\n`
        if format == "github":
            lines = result.out.splitlines()
            assert lines and all(line.startswith("::error file=") for line in lines)
            assert all(_runner_parse(line)[0] == "error" for line in lines) and "z,%25:" in result.out


def test_diff_of_hostile_names_is_neutral_in_every_format(run_cli, tmp_path: Path) -> None:
    old = _workspace(tmp_path / "old", HOSTILE, "::error::shoulder\n::warning::j", "::error::q\n#x", ["::error::ep"])
    new = _workspace(tmp_path / "new", HOSTILE[::-1][1:], "::error::shoulder\n::warning::j", "::error::q\n#x", ["::error::ep"])
    for format in ("text", "markdown", "json"):
        result = run_cli("diff", str(old), str(new), "--format", format)
        assert result.code == 0, result.err
        _assert_neutral(result.out)
        _assert_neutral(result.err)
        if format == "markdown":
            _assert_inert_markdown(result.out)
        if format == "text":
            assert "::error::shoulder\\n::warning::j" in result.out or "removed" in result.out


def test_huge_names_keep_every_line_bounded(run_cli, tmp_path: Path) -> None:
    huge = "L" * 1_000_000
    refused = _workspace(tmp_path / "refused", [huge], "J" * 1_000_000, "q", ["ep"], map_to="K" * 1_000_000)
    for format in ("text", "github", "json"):
        result = run_cli("validate", str(refused), "--format", format)
        assert result.code == 1
        _assert_neutral(result.out, github=format == "github")
        _assert_neutral(result.err)
        assert re.search(r"\(1,0\d\d,\d\d\d characters\)", result.out + result.err)  # shortened, with its length
    accepted = _workspace(tmp_path / "accepted", [huge, "M" * 300_000], "shoulder", "q", ["ep"])
    result = run_cli("validate", str(accepted))
    if result.code == 0:  # a URDF with so long a link name may also be refused; either way no line grows
        for format in ("text", "markdown"):
            shown_plan = run_cli("plan", str(accepted), "--format", format)
            assert shown_plan.code == 0
            _assert_neutral(shown_plan.out)
            if format == "markdown":
                _assert_inert_markdown(shown_plan.out)
    _assert_neutral(result.out)
    _assert_neutral(result.err)


def test_file_names_that_would_be_workflow_commands_are_neutral(run_cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    Path("::error::bad.yaml").write_text("version: 1\n")
    Path("::warning::skip.yaml").write_text("just: data\n")
    for format in ("text", "github", "json"):
        result = run_cli("validate", "::error::bad.yaml", "::warning::skip.yaml", "--skip-non-configs", "--format", format)
        assert result.code == 1
        _assert_neutral(result.out, github=format == "github")
        _assert_neutral(result.err)
        assert "error::bad.yaml" in (result.out + result.err).replace("%3A", ":") and "skipped: ::warning::skip.yaml" in result.err
    github = run_cli("validate", "::error::bad.yaml", "--format", "github").out.splitlines()
    assert github and all(line.startswith("::error file=%3A%3Aerror%3A%3Abad.yaml,") for line in github)


# ------------------------------------------------------------------------------------------------ logging, summary


def test_every_logged_line_is_neutral(capsys: pytest.CaptureFixture[str]) -> None:
    with command_logging(logging.INFO):
        LOGGER.info("note: joint '%s'", "x\n::error::forged\x1b[31m")
        LOGGER.info("table\n::warning::row\n  ::add-mask::s")
        LOGGER.warning("w" * 10**6)
    err = capsys.readouterr().err
    assert err.splitlines()[:4] == ["note: joint 'x", "\\::error::forged\\x1b[31m'", "table", "\\::warning::row"]
    _assert_neutral(err)


def test_the_failure_summary_has_one_line_per_problem_each_escaped() -> None:
    failed = SegmentResult(
        "::error::seg\x1b",
        Path("out/x.rrd"),
        "failed",
        "h",
        reason="error: a.yaml:3:1: first problem\nerror: a.yaml:4:1: second problem\n::error::third\r::x",
    )
    bug = SegmentResult("ok", Path("out/y.rrd"), "bug", "h", reason="Traceback ...\n  File x\nKeyError: '::error::k'")
    written = SegmentResult("w", Path("out/z.rrd"), "written", "h", frames=5)
    lines = summary_table((failed, bug, written)).split("\n")
    assert len(lines) == 1 + 3 + 1 + 1 and " | " not in "\n".join(lines)
    assert lines[1].split()[0] == "\\::error::seg\\x1b" and lines[1].endswith("error: a.yaml:3:1: first problem")
    assert lines[2].strip() == "error: a.yaml:4:1: second problem" and lines[3].strip() == "\\::error::third\\r::x"
    assert lines[4].endswith("KeyError: '::error::k'") and lines[5].split()[:4] == ["w", "5", "0.00", "written"]
    column = lines[0].index("reason")
    assert lines[2][:column] == lines[3][:column] == " " * column


def test_check_shows_hostile_names_neutral(run_cli, hostile: Path) -> None:
    """`check`'s text names each source value and joint: a newline in one must not start a workflow command line."""
    result = run_cli("check", str(hostile))
    assert result.code in (0, 3), result.err
    _assert_neutral(result.out)
    _assert_neutral(result.err)
    assert "::error::q\\n#x -> ::error::shoulder\\n::warning::j" in result.out


def test_init_of_a_urdf_with_hostile_names_writes_yaml_that_reads_back(run_cli, tmp_path: Path) -> None:
    """The names go into keys, values and comments of the scaffold: a newline in a comment would end it, and the rest
    of the name would be YAML (or a workflow command on stdout)."""
    urdf = tmp_path / "h.urdf"
    urdf.write_text(_urdf(HOSTILE, "j\n::warning::x: y"), encoding="utf-8")
    result = run_cli("init", "--urdf", str(urdf))
    assert result.code == 0, result.err
    _assert_neutral(result.out)
    _assert_neutral(result.err)
    data = yaml.safe_load(result.out)
    assert data["robots"]["error_rob_x"]["joints"]["map"] == {"j\n::warning::x: y": "j\n::warning::x: y"}  # keys made safe
