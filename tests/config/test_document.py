import re
from pathlib import Path

import pytest
import yaml

from urdf_pipeline.config import document
from urdf_pipeline.config.document import format_path, load_document, parse_document
from urdf_pipeline.errors import UserError, Where


def test_lines_are_kept_for_every_key_and_item() -> None:
    doc = parse_document("a: 1\nb:\n  c: [1, 2]\n  d:\n    - x: 1\n      y: 2\n", Path("f.yaml"))
    assert doc.data == {"a": 1, "b": {"c": [1, 2], "d": [{"x": 1, "y": 2}]}}
    assert doc.where("b", "d", 0, "y").line == 6
    assert doc.where("b", "d", 0, "y").path == "b.d[0].y"
    assert doc.where("b", "missing").line == 2  # nearest existing ancestor


def test_syntax_error_reports_its_line() -> None:
    with pytest.raises(UserError) as error:
        parse_document("a: 1\nb: [1, 2\nc: 3\n", Path("f.yaml"))
    assert error.value.where is not None and error.value.where.line == 3
    assert "YAML syntax error" in error.value.message


def test_duplicate_keys_are_refused_instead_of_silently_overwritten() -> None:
    with pytest.raises(UserError) as error:
        parse_document("map:\n  j1: a\n  j1: b\n", Path("f.yaml"))
    assert error.value.where.line == 3
    assert "duplicate key 'j1' (first at line 2)" in error.value.message


def test_format_path() -> None:
    assert format_path(("edges", 0, "child")) == "edges[0].child"


def test_scientific_notation_is_a_number_as_in_json() -> None:
    doc = parse_document("t: [1e-3, -2E+4, 1, 0.5, 1e3x]\n", Path("f.yaml"))
    assert doc.data == {"t": [0.001, -20000.0, 1, 0.5, "1e3x"]}


# Hostile YAML: every refusal is a UserError at a line and column, found within the bounds (MAX_BYTES, MAX_NODES,
# MAX_DEPTH), never an exception that the CLI would report as a bug.


def _refused(text: str, file: Path = Path("f.yaml")) -> UserError:
    with pytest.raises(UserError) as error:
        parse_document(text, file)
    assert error.value.where is not None and error.value.where.line >= 1 and error.value.where.column >= 1, error.value.lines()
    return error.value


def _bomb(levels: int) -> str:
    """A billion laughs: `levels` anchors of 9 aliases each to the one before."""
    text = "version: 1\nl0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n"
    return text + "".join(f"l{n}: &l{n} [{', '.join([f'*l{n - 1}'] * 9)}]\n" for n in range(1, levels))


def test_ordinary_anchors_and_merge_keys_keep_working() -> None:
    text = (
        "defaults: &lim {slack: 2.0, on_violation: clamp}\n"  # 1
        "a: {limits: *lim}\n"
        "b: {limits: *lim}\n"
        "c:\n"
        "  <<: *lim\n"  # 5
        "  slack: 3.0\n"  # an own key overrides a merged one
        "d: {<<: [{x: 1, slack: 4}, *lim], y: 2}\n"  # of several merged mappings the first wins
        "names: &names [j1, j2]\n"
        "e: *names\n"
    )
    doc = parse_document(text, Path("f.yaml"))
    limits = {"slack": 2.0, "on_violation": "clamp"}
    assert doc.data["a"] == doc.data["b"] == {"limits": limits}
    assert doc.data["c"] == {"slack": 3.0, "on_violation": "clamp"}
    assert doc.data["d"] == {"x": 1, "slack": 4, "on_violation": "clamp", "y": 2}
    assert doc.data["e"] == ["j1", "j2"]
    assert doc.where("c", "slack").line == 6 and doc.where("c", "on_violation").line == 1  # a merged key: at its anchor
    assert doc.where("b", "limits", "slack").line == 1


def test_a_merge_key_needs_a_mapping_and_own_keys_still_must_not_repeat() -> None:
    error = _refused("base: &b {a: 1}\nc: {<<: [*b, 3]}\n")
    assert (error.where.line, error.where.column) == (2, 14) and "'<<' merges a mapping or a list of mappings" in error.message
    error = _refused("base: &b {a: 1}\nc:\n  <<: *b\n  a: 2\n  a: 3\n")
    assert error.where.line == 5 and "duplicate key 'a' (first at line 4)" in error.message


def test_an_alias_bomb_is_refused_at_the_alias_without_being_expanded() -> None:
    error = _refused(_bomb(9))  # 9^9 strings once expanded
    assert (error.where.line, error.where.column) == (7, 10)  # the first *l4 in l5
    assert "more than 100,000 YAML nodes" in error.message
    assert "*l4 repeats &l4 (line 6), which alone stands for 66,430 nodes" in error.message
    assert "(an alias bomb?)" in error.message
    assert _refused(_bomb(40)).message == error.message  # 9^39 would never finish: it is counted, not expanded


def test_the_node_bound_counts_aliases_and_plain_nodes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(document, "MAX_NODES", 100)
    text = "a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9]\nb: [*a, *a, *a, *a, *a, *a, *a, *a]\n"  # 2 + 10 + 1 + 1 + 8 * 10 = 94
    assert parse_document(text, Path("f.yaml")).data["b"][7] == list(range(1, 10))
    error = _refused(text.replace("*a]", "*a, *a]"))  # 104
    assert (error.where.line, error.where.column) == (2, 37) and "more than 100 YAML nodes: *a repeats &a (line 1)" in error.message
    error = _refused("[" + ", ".join(["0"] * 100) + "]\n")  # 101 nodes, no alias
    assert (error.where.line, error.where.column) == (1, 299) and "more than 100 YAML nodes (keys, values and list items)" in error.message


@pytest.mark.parametrize(
    "text, line, column",
    [
        ("a: " + "[" * 2000 + "]" * 2000 + "\n", 1, 103),
        ("a: " + "{b: " * 2000 + "1" + "}" * 2000 + "\n", 1, 397),  # the key b of the 100th level
        ("- " * 2000 + "x\n", 1, 201),
        ("".join(" " * level + "k:\n" for level in range(2000)), 100, 100),  # block mappings, 1-space indentation
        ("k: " + "[" * 2000 + "\n", 1, 103),  # unclosed as well: the depth is found first
    ],
    ids=["flow_sequences", "flow_mappings", "block_sequences", "block_mappings", "unclosed"],
)
def test_nesting_2000_levels_deep_is_refused_at_level_101(text: str, line: int, column: int) -> None:
    error = _refused(text)
    assert (error.where.line, error.where.column) == (line, column)
    assert error.message.startswith("nested more than 100 levels deep")


def test_nesting_through_aliases_counts_too() -> None:
    text = "a0: &a0 [x]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, 120))
    error = _refused(text)
    assert (error.where.line, error.where.column) == (99, 12)
    assert "nested more than 100 levels deep: *a97 puts &a97 (line 98), 99 level(s) deep, at level 3" in error.message
    assert parse_document("a: " + "[" * 98 + "]" * 98 + "\n", Path("f.yaml")).data["a"] is not None  # 99 levels: fine


@pytest.mark.parametrize("text", ["a: &a [*a]\n", "a: &a {b: {c: *a}}\n"])
def test_an_alias_inside_its_own_anchor_is_refused(text: str) -> None:
    error = _refused(text)
    assert error.where.line == 1 and "the alias *a is inside its own anchor &a (line 1)" in error.message


@pytest.mark.parametrize(
    "text, shown",
    [
        ("a: !custom 1\n", "!custom"),
        ("a: !custom {b: 1}\n", "!custom"),
        ("a: !!python/name:os.system\n", "!!python/name:os.system"),
        ("a: !!python/object/apply:os.system [ls]\n", "!!python/object/apply:os.system"),
        ("a: !!python/object/new:subprocess.Popen {args: [ls]}\n", "!!python/object/new:subprocess.Popen"),
        ("a: !!binary aGVsbG8=\n", "!!binary"),
        ("a: !!set {x, y}\n", "!!set"),
        ("a: !!omap [b: 1]\n", "!!omap"),
        ("a: !!str [1]\n", "!!str"),  # a standard scalar tag on a sequence
        ("%TAG !p! tag:yaml.org,2002:python/\n---\na: !p!name:os.system\n", "!!python/name:os.system"),
    ],
)
def test_a_tag_that_is_not_plain_data_is_refused_at_its_line_and_column(text: str, shown: str) -> None:
    error = _refused(text)
    assert error.where.column == 4 and error.where.line == text.count("\n")
    assert f"the tag {shown} is not allowed (nothing was constructed or run)" in error.message


def test_plain_data_tags_are_accepted() -> None:
    text = "a: !!str 1\nb: !!int '2'\nc: !!float 3\nd: ! 4\ne: !!map {x: !!null ''}\nf: !!seq [!!bool yes]\n"
    assert parse_document(text, Path("f.yaml")).data == {"a": "1", "b": 2, "c": 3.0, "d": 4, "e": {"x": None}, "f": [True]}


def test_a_python_tag_runs_nothing(tmp_path: Path) -> None:
    marker = tmp_path / "ran"
    _refused(f"a: !!python/object/apply:os.system ['touch {marker}']\n")
    _refused(f"a: !!python/object/apply:subprocess.check_call [[touch, {marker}]]\n")
    assert not marker.exists()


def test_the_package_loads_yaml_only_safely() -> None:
    """Every parse goes through document.py's SafeLoader subclass (or yaml.safe_load); no unsafe loader anywhere."""
    package = Path(document.__file__).parent
    unsafe = re.compile(r"yaml\.(load|load_all|full_load|unsafe_load|unsafe_load_all)\(|FullLoader|UnsafeLoader|yaml\.Loader\b")
    found = [f"{file.name}:{line}" for file in package.rglob("*.py") for line in unsafe.findall(file.read_text(encoding="utf-8"))]
    assert not found, found


@pytest.mark.parametrize(
    "text, reason",
    [("a: 2024-13-45\n", "cannot read 2024-13-45 as !!timestamp (month must be in 1..12)"), ("a: " + "7" * 5000 + "\n", "as !!int")],
)
def test_a_scalar_python_cannot_construct_is_refused(text: str, reason: str) -> None:
    error = _refused(text)
    assert (error.where.line, error.where.column, error.where.path) == (1, 4, "a")
    assert reason in error.message and "quote it to keep it as text" in error.message


@pytest.mark.parametrize(
    "text, line, column, opened",
    [
        ("x: 1\nmap: {a: 1, b: 2\nc: 3\n", 3, 2, "in the flow mapping opened at line 2, column 6"),
        ("x: 1\nmap: {a: 1, b: 2\n", 3, 1, "in the flow mapping opened at line 2, column 6"),
        ("x: 1\nl: [1, 2,\n  a: b: c,\n  3]\n", 3, 7, "in the flow sequence opened at line 2, column 4"),
        ("l: [1, {a: 1},\n  [2, {b: 2 c: 3}]]\n", 2, 14, "in the flow mapping opened at line 2, column 7"),  # the innermost
        ("l: [1, 2]\nm: {a: [1],\n  b: 2 c: 3}\n", 3, 9, "in the flow mapping opened at line 2, column 4"),  # not the closed [1]
    ],
)
def test_a_syntax_error_in_a_flow_collection_names_where_it_opened(text: str, line: int, column: int, opened: str) -> None:
    error = _refused(text)
    assert (error.where.line, error.where.column) == (line, column), error.lines()
    assert error.message.startswith("YAML syntax error: ") and opened in error.message, error.message


def test_a_syntax_error_outside_flow_collections_is_unchanged() -> None:
    error = _refused("l: [1, 2]\na: 1\n b: 2\n")
    assert error.message == "YAML syntax error: mapping values are not allowed here"


@pytest.mark.parametrize(
    "content, line, column, message",
    [
        (b"a: 1\nb: \xff\xfe\n", 2, 4, "byte 0xff is not UTF-8: the config file must be UTF-8 text; save it as UTF-8"),
        (b"a: 1\nb: \xc3\xa9t\xc3\xa9 \xe9\n", 2, 8, "byte 0xe9 is not UTF-8"),  # the column counts characters
        ("a: 1\n".encode("utf-16"), 1, 1, "(it starts like UTF-16)"),
        (b"a: 1\nb: x\x00y\n", 2, 5, "a NUL byte: YAML text cannot hold it"),
        (b"a: 1\r\nb: \x1b[31m\n", 2, 4, "the control character U+001B"),
    ],
    ids=["latin1", "column", "utf16", "nul", "escape"],
)
def test_bytes_that_are_not_yaml_text_are_refused_at_their_line(
    content: bytes, line: int, column: int, message: str, tmp_path: Path
) -> None:
    config = tmp_path / "c.yaml"
    config.write_bytes(content)
    with pytest.raises(UserError) as error:
        load_document(config)
    assert error.value.where == Where(config, line, "", column)
    assert message in error.value.message


def test_a_file_beyond_the_size_bound_is_refused_before_parsing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    config = tmp_path / "c.yaml"
    config.write_bytes(b"a: [" + b"1, " * (document.MAX_BYTES // 3) + b"]\n")  # beyond 4 MB
    monkeypatch.setattr(document, "_Loader", None)  # never reached
    with pytest.raises(UserError) as error:
        load_document(config)
    assert error.value.where == Where(config, 0)  # the file as a whole
    assert error.value.message == "the config file is larger than 4 MB, the most this tool reads as YAML or JSON: is this the right file?"


def test_a_config_that_cannot_be_read_is_a_user_error(tmp_path: Path) -> None:
    with pytest.raises(UserError) as error:
        load_document(tmp_path)  # a directory
    assert error.value.where == Where(tmp_path, 0) and error.value.message == "the config file is a folder, not a file"


HOSTILE_SIDECARS = {  # name -> (file name, content, line, column, message): edges files go through the same parser
    "alias_bomb": ("edges.yaml", _bomb(9).replace("version: 1\n", "").encode(), 6, 10, "more than 100,000 YAML nodes: *l4 repeats"),
    "python_tag": ("edges.yaml", b"- parent: world\n  child: !!python/name:os.system\n", 2, 10, "the tag !!python/name:os.system"),
    "deep_yaml": ("edges.yaml", b"- " * 2000 + b"x\n", 1, 201, "nested more than 100 levels deep"),
    "deep_json": ("edges.json", b"[" * 2000 + b"]" * 2000 + b"\n", 1, 101, "nested more than 100 levels deep"),  # beyond json's recursion
    "deeper_than_bound_json": ("edges.json", b"[" * 300 + b"]" * 300 + b"\n", 1, 101, "nested more than 100 levels deep"),
    "nul_json": ("edges.json", b'[\n  {"parent": "world\x00"}\n]\n', 2, 20, "a NUL byte"),
    "latin1": ("edges.yaml", b"- parent: world\n  child: caf\xe9\n", 2, 13, "byte 0xe9 is not UTF-8: the edges file must be UTF-8"),
    "too_large": ("edges.yaml", b"# padding\n" * (document.MAX_BYTES // 10 + 1), 0, 0, "the edges file is larger than 4 MB"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE_SIDECARS))
def test_a_hostile_edges_file_is_a_user_error_at_its_line(case: str, examples_dir: Path, run_cli) -> None:
    filename, content, line, column, message = HOSTILE_SIDECARS[case]
    sidecar = examples_dir / "calib" / f"hostile_{case}" / filename
    sidecar.parent.mkdir(parents=True, exist_ok=True)
    sidecar.write_bytes(content)
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text(encoding="utf-8"))
    data["edges"].append({"file": f"calib/hostile_{case}/{filename}"})
    config = examples_dir / f"hostile_sidecar_{case}.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")

    result = run_cli("validate", str(config))

    assert result.code == 1, result.err
    assert "Traceback" not in result.err and "internal error" not in result.err
    where = f"{sidecar}:{line}:{column}" if line else str(sidecar)
    assert f"error: {where}: " in result.err and message in result.err, result.err


def test_a_config_that_is_a_fifo_is_refused_without_waiting(tmp_path: Path) -> None:
    """Opening a FIFO waits for a writer that never comes: `validate A FIFO C` would hang on B. It is refused by its
    kind before it is opened (in a child process, so that a regression fails here instead of hanging the suite)."""
    import os
    import subprocess
    import sys

    fifo = tmp_path / "c.yaml"
    os.mkfifo(fifo)
    code = "import sys; from urdf_pipeline import cli; sys.exit(cli.main(['validate', sys.argv[1]]))"
    result = subprocess.run([sys.executable, "-c", code, str(fifo)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 1, result.stderr
    assert result.stderr.splitlines() == [f"error: {fifo}: the config file {fifo} is a FIFO, not a regular file or folder; name a file"]
