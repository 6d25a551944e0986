"""A xacro file from a pull request runs no code, reads nothing outside its roots, copies nothing from the environment,
and cannot exhaust the runner; real xacro files expand exactly as xacro itself expands them."""

from __future__ import annotations

import ast
import contextlib
import io
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rtbdata
import yaml

from urdf_pipeline.confine import confinement_for
from urdf_pipeline.errors import UserError
from urdf_pipeline.examples import example_robot_data_share, write_joint_parquet
from urdf_pipeline.urdf.meshes import package_roots
from urdf_pipeline.urdf.xacro_guard import XacroRequest, expand_xacro
from urdf_pipeline.urdf.xacro_sandbox import refused_name

RTB_XACRO = Path(rtbdata.__file__).parent / "xacro"
XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'
ROBOT_TAIL = (
    '<link name="base"/><link name="l1"/><joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>'
    '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
)
# The payload: a name inside a comprehension, which xacro 2.x's own check does not see.
COMPREHENSION_PAYLOAD = (
    "${[c.__init__.__globals__['system']('touch MARKER') for x in [1] for c in ().__class__.__base__.__subclasses__() "
    "if c.__name__ == '_wrap_close'][0]}"
)
# $(eval) checks only for '__'; its expression is built from a property, so it may hold the parentheses $(...) cannot.
EVAL_PAYLOAD = (
    '<xacro:property name="code" value="exec(\'import os; os.system(&quot;touch MARKER&quot;)\', {})"/><link name="$(eval ${code})"/>'
)


def write_robot(directory: Path, name: str, body: str, args: dict[str, str] | None = None, **robot: object) -> Path:
    """`name`.urdf.xacro holding `body` (plus one revolute joint j1) and a config `name`.yaml that validates it."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / f"{name}.urdf.xacro").write_text(f'<robot name="r" {XACRO_NS}>{body}{ROBOT_TAIL}</robot>', encoding="utf-8")
    write_joint_parquet(directory / "d.parquet", np.zeros((3, 1)))
    urdf: dict[str, object] = {"xacro": f"{name}.urdf.xacro", **({"args": args} if args else {})}
    config = {
        "version": 1,
        "sources": {"s": {"parquet": "d.parquet", "column": "observation.state", "index": "frame_index", "names": ["j"]}},
        "robots": {"arm": {"urdf": urdf, **robot, "joints": {"source": "s", "map": {"j": "j1"}}}},
        "output": {"path": "out/x.rrd", "application_id": "x", "segment": "x"},
    }
    path = directory / f"{name}.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path


def expand(directory: Path, body: str) -> str:
    """The guarded expansion of a xacro file holding `body`, for a config in `directory`."""
    config = write_robot(directory, "r", body)
    xacro_file = directory / "r.urdf.xacro"
    return expand_xacro(XacroRequest(xacro_file, "r.urdf.xacro", {}, {}, confinement_for(config)), None)


def assert_user_error(result, config: Path, *expected: str) -> None:
    assert result.code == 1, f"exit {result.code}\n{result.err}"
    assert "Traceback" not in result.err and "internal error" not in result.err, result.err
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    assert errors and all(line.startswith(f"error: {config}:") for line in errors), result.err
    for text in expected:
        assert text in result.err, f"{text!r} not in:\n{result.err}"


# --- code -----------------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "expression",
    ["pi / 2", "[x * 2 for x in l]", "python.len(a)", "cfg.type", "cfg['key']", "a if b else c", "(lambda v: v + 1)(x)", "'%s' % x"],
)
def test_ordinary_expressions_pass_the_check(expression: str) -> None:
    assert refused_name(ast.parse(expression, mode="eval")) is None


@pytest.mark.parametrize(
    ("expression", "name"),
    [
        ("().__class__", "__class__"),
        ("_private", "_private"),
        ("[y for y in [x.__mro__ for x in l]]", "__mro__"),  # a nested scope
        ("(lambda: [z for z in l if z._x])()", "_x"),
        ("(x for x in l).gi_frame", "gi_frame"),
        ("g.f_back.f_globals", "f_back"),  # the first in reading order
        ("e.tb_frame", "tb_frame"),
        ("f.co_consts", "co_consts"),
        ("'{0.x}'.format(o)", "format"),
        ("s.format_map(m)", "format_map"),
        ("(lambda _a: 1)(2)", "_a"),
        ("dict(_a=1)", "_a"),
    ],
)
def test_names_that_reach_python_internals_are_refused(expression: str, name: str) -> None:
    assert refused_name(ast.parse(expression, mode="eval")) == name


def _unguarded_xacro(xacro_file: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    """xacro itself (no guard), in a child process: it is what runs the payloads the guard must stop."""
    command = f"import sys, xacro; sys.argv = ['xacro', {str(xacro_file)!r}]; xacro.main()"
    return subprocess.run([sys.executable, "-c", command], cwd=cwd, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("payload", ["comprehension", "eval"])
def test_code_in_a_xacro_expression_never_runs(payload: str, tmp_path: Path, run_cli) -> None:
    marker = tmp_path / "marker"
    if payload == "comprehension":
        body = f'<xacro:property name="p" value="{COMPREHENSION_PAYLOAD}"/><link name="${{p}}"/>'
    else:
        body = EVAL_PAYLOAD
    body = body.replace("MARKER", str(marker))
    # The payload is real: xacro alone runs it.
    control = write_robot(tmp_path / "control", "r", body)
    _unguarded_xacro(control.parent / "r.urdf.xacro", control.parent)
    assert marker.exists(), "the payload did not run under plain xacro: the test proves nothing"
    marker.unlink()

    config = write_robot(tmp_path / "pr", "evil", body)
    for command in ("validate", "plan"):
        result = run_cli(command, str(config))
        assert_user_error(result, config, "evil.urdf.xacro")
        assert not marker.exists(), f"{command} ran the xacro payload"
    if payload == "comprehension":
        assert "expression '[c.__init__.__globals__" in result.err and "is refused: it uses '__" in result.err
    else:
        assert "name 'exec' is not defined" in result.err  # $(eval) gets no builtins that run code


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        (
            '<xacro:property name="g" value="${python.list(g := (g.gi_frame.f_back.f_back.f_globals for x in [1]))}"/><link name="${g}"/>',
            "uses 'gi_frame'",
        ),
        ('<xacro:property name="f" value="{0.parent}"/><link name="${f.format(xacro)}"/>', "uses 'format'"),
        ('<xacro:property name="v" value="${python[\'vars\']}"/><link name="${v(python.type)}"/>', "python.vars() is refused"),
        ('<xacro:property name="e" value="open"/><link name="$(eval ${e})"/>', "name 'open' is not defined"),
    ],
    ids=["generator-frame", "str-format", "vars-by-key", "eval-builtins"],
)
def test_other_ways_to_python_internals_are_closed(body: str, expected: str, tmp_path: Path, run_cli) -> None:
    config = write_robot(tmp_path, "evil", body)
    assert_user_error(run_cli("validate", str(config)), config, "evil.urdf.xacro", expected)


def test_the_refusal_names_the_included_file(tmp_path: Path, run_cli) -> None:
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "inner.xacro").write_text(f'<robot {XACRO_NS}><link name="${{().__class__}}"/></robot>', encoding="utf-8")
    config = write_robot(tmp_path, "outer", '<xacro:include filename="parts/inner.xacro"/>')
    assert_user_error(run_cli("validate", str(config)), config, "xacro file parts/inner.xacro: expression '().__class__' is refused")


def test_xacro_s_warnings_quoting_the_file_are_neutral(tmp_path: Path, run_cli) -> None:
    """xacro's warning on an include that matches nothing quotes the filename, which a pull request writes: a newline
    in it must not start a line GitHub reads as a workflow command."""
    config = write_robot(tmp_path, "r", '<xacro:include filename="nothing*&#10;::error file=x::forged"/>')
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err
    assert "matched no files" in result.err
    assert not [line for line in result.err.splitlines() if line.lstrip().startswith("::")], result.err


# --- environment ----------------------------------------------------------------------------------------------------


def test_env_is_refused_and_optenv_gives_its_default(tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CI_TOKEN", "s3cr3t-token-value")
    for body in ('<link name="$(env CI_TOKEN)"/>', '<xacro:property name="e" value="env(\'CI_TOKEN\')"/><link name="$(eval ${e})"/>'):
        config = write_robot(tmp_path, "env", body)
        assert_user_error(run_cli("plan", str(config)), config, "$(env CI_TOKEN) is refused", "urdf.args {CI_TOKEN: VALUE}")
    body = '<xacro:property name="o" value="optenv(\'CI_TOKEN\', \'other\')"/><link name="a$(optenv CI_TOKEN fallback)"/><link name="b$(eval ${o})"/>'
    text = expand(tmp_path / "optenv", body)
    assert "s3cr3t" not in text
    assert '<link name="afallback"/>' in text and '<link name="bother"/>' in text


# --- files ----------------------------------------------------------------------------------------------------------


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A folder beside the config's folder, holding a valid xacro and YAML file."""
    folder = tmp_path / "outside"
    folder.mkdir()
    (folder / "part.xacro").write_text(f'<robot {XACRO_NS}><link name="stolen"/></robot>', encoding="utf-8")
    (folder / "values.yaml").write_text("secret: 1\n", encoding="utf-8")
    return folder


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        (
            '<xacro:include filename="../outside/part.xacro"/>',
            "included or loaded file {pr}/../outside/part.xacro (resolves to {outside}/part.xacro) is outside the config's folder",
        ),
        (
            '<xacro:include filename="../outside/*.xacro"/>',
            "include pattern folder {pr}/../outside (resolves to {outside}) is outside the config's folder",
        ),
        (
            "<link name=\"${xacro.load_yaml('../outside/values.yaml')}\"/>",
            "included or loaded file {pr}/../outside/values.yaml (resolves to {outside}/values.yaml) is outside",
        ),
        ('<xacro:include filename="link/part.xacro"/>', "(resolves to {outside}/part.xacro) is outside"),  # a symlink out
        ("<link name=\"${xacro.load_yaml('.git/config')}\"/>", "is inside a .git folder"),
        ('<xacro:include filename="$(find pkg)/part.xacro"/>', "$(find pkg) folder {outside} is outside"),
    ],
    ids=["include", "include-glob", "load-yaml", "symlink", "git", "find"],
)
def test_xacro_reads_only_inside_the_roots(body: str, expected: str, tmp_path: Path, outside: Path, run_cli) -> None:
    config_dir = tmp_path / "pr"
    config_dir.mkdir()
    (config_dir / "link").symlink_to(outside, target_is_directory=True)
    (config_dir / ".git").mkdir()
    (config_dir / ".git" / "config").write_text("token: 1\n", encoding="utf-8")
    config = write_robot(config_dir, "reader", body, package_paths={"pkg": "../outside"})
    result = run_cli("validate", str(config))
    assert_user_error(result, config, "xacro file reader.urdf.xacro: ", expected.format(outside=outside, pr=config_dir))
    assert "stolen" not in result.err


def test_the_same_includes_inside_the_roots_expand(tmp_path: Path, outside: Path) -> None:
    """Control for the refusals above: allowed by URDF_PIPELINE_ALLOW_PATHS, each form reads its file."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(outside))
        text = expand(
            tmp_path / "pr",
            '<xacro:include filename="../outside/*.xacro"/><link name="v${xacro.load_yaml(\'../outside/values.yaml\').secret}"/>',
        )
    assert '<link name="stolen"/>' in text and '<link name="v1"/>' in text


# --- exhaustion -----------------------------------------------------------------------------------------------------


def _laughs(levels: int = 12) -> str:
    """Properties that each repeat the one before ten times: 10 ** 13 characters at the last."""
    properties = ['<xacro:property name="p0" value="aaaaaaaaaa"/>']
    properties += [f'<xacro:property name="p{i}" value="{f"${{p{i - 1}}}" * 10}"/>' for i in range(1, levels + 1)]
    return "".join(properties) + f'<link name="${{p{levels}}}"/>'


def _big_output() -> str:
    """72 MB of link names: each expression is allowed, the URDF is not."""
    return '<xacro:property name="a" value="${\'a\' * 9000000}"/>' + "".join(f'<link name="${{a}}{i}"/>' for i in range(8))


def _bounded() -> None:
    """For the CLI child of the tests below: if the guard regressed, they fail instead of taking the machine down."""
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
    resource.setrlimit(resource.RLIMIT_CPU, (240, 240))


def _session(sid: int) -> list[int]:
    """The processes still in session `sid`."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, IndexError, ValueError):
            if int(stat.read_text().rsplit(")", 1)[1].split()[3]) == sid:
                found.append(int(stat.parent.name))
    return found


def validate_in_a_bounded_process(config: Path, **environment: str) -> subprocess.CompletedProcess[str]:
    """`urdf-pipeline validate CONFIG` in its own session, bounded; asserts it left no process behind."""
    child = subprocess.Popen(
        [sys.executable, "-m", "urdf_pipeline", "validate", str(config)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, **environment},
        preexec_fn=_bounded,
        start_new_session=True,
    )
    try:
        out, err = child.communicate(timeout=240)
    except subprocess.TimeoutExpired:
        os.killpg(child.pid, signal.SIGKILL)
        child.communicate()
        raise AssertionError("validate did not end: the xacro guard's bounds failed") from None
    if Path("/proc/self/stat").exists():
        left = _session(child.pid)
        for pid in left:
            os.kill(pid, signal.SIGKILL)
        assert not left, f"processes left behind: {left}"
    return subprocess.CompletedProcess(child.args, child.returncode, out, err)


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("<link name=\"${'a' * 10**10}\"/>", "is too large to evaluate: repeating a str of 1 items 10,000,000,000 times"),
        ('<link name="${10**10**10}"/>', "is too large to evaluate: 10 ** 10000000000 has more than 1,048,576 bits"),
        ('<xacro:macro name="m"><xacro:m/></xacro:macro><xacro:m/>', "expansion nested too deep"),
        ('<xacro:include filename="bomb.urdf.xacro"/>', "expansion nested too deep"),  # includes itself
        (_laughs(), "needs more than 1024 MB of memory"),
        ('<link name="${python.list(python.range(10**9))}"/>', "needs more than 1024 MB of memory"),
        (_big_output(), "is larger than 16 MB of URDF text"),
    ],
    ids=["repeat", "power", "recursive-macro", "recursive-include", "property-laughs", "big-list", "big-output"],
)
def test_exhaustion_ends_in_a_user_error(body: str, expected: str, tmp_path: Path) -> None:
    config = write_robot(tmp_path, "bomb", body)
    result = validate_in_a_bounded_process(config)
    assert result.returncode == 1, result.stderr
    assert "Traceback" not in result.stderr
    assert f"error: {config}:11:5: robots.arm.urdf: " in result.stderr and "bomb.urdf.xacro" in result.stderr, result.stderr
    assert expected in result.stderr, result.stderr


def test_an_endless_expression_is_stopped_at_the_time_bound(tmp_path: Path) -> None:
    config = write_robot(tmp_path, "spin", '<link name="${python.sum(python.range(10**15))}"/>')
    result = validate_in_a_bounded_process(config, URDF_PIPELINE_XACRO_TIMEOUT="2")
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert "xacro expansion of spin.urdf.xacro did not end within 2 s and was stopped" in result.stderr
    assert "URDF_PIPELINE_XACRO_TIMEOUT" in result.stderr


def test_a_child_that_cannot_even_start_is_a_user_error(tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    config = write_robot(tmp_path, "r", "")
    monkeypatch.setenv("URDF_PIPELINE_XACRO_MEMORY_MB", "8")  # too little for Python to import xacro
    assert_user_error(run_cli("validate", str(config)), config, "xacro expansion of r.urdf.xacro needs more than 8 MB of memory")
    monkeypatch.setenv("URDF_PIPELINE_XACRO_MEMORY_MB", "lots")
    assert_user_error(run_cli("validate", str(config)), config, "URDF_PIPELINE_XACRO_MEMORY_MB='lots' must be a positive number")
    monkeypatch.delenv("URDF_PIPELINE_XACRO_MEMORY_MB")
    for text in ("nan", "inf", "-3"):  # one reading of every child's bound (process.bound_from_environment)
        monkeypatch.setenv("URDF_PIPELINE_XACRO_TIMEOUT", text)
        assert_user_error(run_cli("validate", str(config)), config, f"URDF_PIPELINE_XACRO_TIMEOUT='{text}' must be a positive number")


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("<link name='a'", "xacro failed on r.urdf.xacro: ExpatError"),
        ("<xacro:nope/>", "xacro failed on r.urdf.xacro: XacroException: unknown macro name: xacro:nope"),
        ("<link name=\"${xacro.fatal('stop here')}\"/>", "stop here"),
        ('<link name="${1/0}"/>', "division by zero when evaluating expression '1/0'"),
    ],
)
def test_xacro_errors_are_user_errors_naming_the_file(body: str, expected: str, tmp_path: Path, run_cli) -> None:
    config = write_robot(tmp_path, "r", "")
    (tmp_path / "r.urdf.xacro").write_text(f'<robot name="r" {XACRO_NS}>{body}</robot>', encoding="utf-8")
    assert_user_error(run_cli("validate", str(config)), config, expected)


# --- real xacro files -----------------------------------------------------------------------------------------------


def _packages() -> dict[str, Path]:
    """Every ROS package rtb-data's xacro files $(find), by name -> its folder (some differ in name)."""
    packages = {folder.name: folder for folder in RTB_XACRO.iterdir() if folder.is_dir()}
    for folder in (RTB_XACRO / "kuka_description").iterdir():
        packages[folder.name] = packages[f"{folder.name}_support"] = folder
    packages["abb_irb140"] = packages["abb_irb140_support"] = RTB_XACRO / "abb_irb140_description"
    packages["ridgeback_description"] = RTB_XACRO / "clearpath_ridgeback_description"
    return packages


def _robot_xacros() -> list[tuple[Path, dict[str, str]]]:
    """rtb-data's xacro files that describe a robot on their own (not macros, materials or accessories), with the args
    they need, and example-robot-data's xacro files."""
    robots: list[tuple[Path, dict[str, str]]] = []
    for path in sorted(RTB_XACRO.glob("**/*.xacro")):
        if path.name.endswith("_macro.xacro") or "accessories" in path.parts or "kuka_resources" in path.parts:
            continue
        if path.parent.name == "robots" and path.parent.parent.name == "qut_frankie_description" and not path.name.endswith(".urdf.xacro"):
            continue  # panda_arm.xacro, hand.xacro: macros that the .urdf.xacro files include
        trossen = path.parent == RTB_XACRO / "trossen_descriptions" / "urdf"
        robots.append((path, {"robot_name": path.name.split(".")[0]} if trossen else {}))
    robots += [(path, {}) for path in sorted(example_robot_data_share().glob("**/*.xacro"))]
    return robots


def _xacro_itself(path: Path, args: dict[str, str], packages: dict[str, Path]) -> str:
    """The text the pipeline produced before the guard: xacro in this process, $(find) from `packages`."""
    import xacro
    import xacro.substitution_args as substitution

    def find(package: str) -> str:
        for root in [*([packages[package]] if package in packages else []), *package_roots(package)]:
            if root.is_dir():
                return str(root)
        raise KeyError(package)

    saved = substitution._eval_find, substitution._eval_dict["find"]
    substitution._eval_find = substitution._eval_dict["find"] = find
    try:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            xacro.init_stacks(str(path))
            document = xacro.parse(None, str(path))
            xacro.process_doc(document, mappings=dict(args))
        return document.toprettyxml(indent="  ")
    finally:
        substitution._eval_find, substitution._eval_dict["find"] = saved


ROBOTS = _robot_xacros()


def test_the_robot_list_covers_rtb_data() -> None:
    assert sum(RTB_XACRO in path.parents for path, _ in ROBOTS) >= 30
    assert (RTB_XACRO / "trossen_descriptions" / "urdf" / "vx300s.urdf.xacro", {"robot_name": "vx300s"}) in ROBOTS  # ALOHA's


@pytest.mark.parametrize(("path", "args"), ROBOTS, ids=[str(path.relative_to(path.parents[2])) for path, _ in ROBOTS])
def test_real_xacro_files_expand_to_the_same_text(path: Path, args: dict[str, str], tmp_path: Path) -> None:
    packages = _packages()
    request = XacroRequest(path, path.name, args, packages, confinement_for(tmp_path / "config.yaml"))
    try:
        before = _xacro_itself(path, args, packages)
    except Exception:  # a file xacro itself cannot expand (kr210l150: ROS 1 syntax) must fail here too, as a user error
        with pytest.raises(UserError, match=f"xacro failed on {path.name}"):
            expand_xacro(request, None)
        return
    assert expand_xacro(request, None) == before
