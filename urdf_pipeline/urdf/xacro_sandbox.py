"""The child process that expands one xacro file, with xacro patched so a file from a pull request runs no code.

xacro 2.x evaluates `${...}` and `$(eval ...)` with Python's eval and checks only the outer names, so a name inside a
comprehension reaches any Python object: here every expression is parsed first, at the point xacro calls eval, and
`**`, `*` and `<<` are checked against a size before they run (what is refused: docs/security.md, Code). Memory, CPU
time and output size are bounded by rlimits set here; the wall clock by xacro_guard, which spawns this.

Protocol: one JSON request on stdin, one JSON answer on stdout: {"text": URDF, "files": [...], "globs": [...]} (every
file xacro read, every include pattern and what it matched: xacro_guard reuses the text while they are unchanged) or
{"error": message}.
"""

from __future__ import annotations

import ast
import builtins
import contextlib
import glob
import json
import os
import re
import sys
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from ..confine import Confinement
from ..errors import UserError
from ..process import limit_this_process

# Names and attributes that lead to Python's internals: dunders and privates, frame/generator/coroutine/traceback/code
# objects (`gen.gi_frame.f_back.f_globals` reaches a module's globals), and str.format, whose fields read attributes.
_REFUSED_NAME = re.compile(r"_")
_REFUSED_ATTRIBUTE = re.compile(r"_|(f|gi|cr|ag|tb|co)_|format$|format_map$")
_BINOP = "urdf-pipeline checked operator"  # not an identifier: no property or expression can name or shadow it
MAX_INT_BITS = 1 << 20  # ~315,000 decimal digits: far beyond any robot, small enough to compute at once
MAX_ITEMS = 10_000_000  # characters or items of one repeated string or list
SHOWN_EXPRESSION = 160  # characters of a refused expression quoted in the message


class Refused(Exception):
    """An expression, file or substitution the sandbox refuses; the message is the user's."""


class _UnknownPackage(Exception):
    pass


class _Sizes(ast.NodeTransformer):
    """`a ** b`, `a * b`, `a << b` -> a call of the size-checking operator."""

    _OPS: dict[type[ast.operator], str] = {ast.Pow: "pow", ast.Mult: "mul", ast.LShift: "lshift"}

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        op = self._OPS.get(type(node.op))
        if op is None:
            return node
        call = ast.Call(ast.Name(_BINOP, ast.Load()), [ast.Constant(op), node.left, node.right], [])
        return ast.copy_location(call, node)


def refused_name(tree: ast.AST) -> str | None:
    """The first name or attribute (in reading order) in `tree`, in any nested scope, that an expression may not use."""
    found: list[tuple[int, int, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _REFUSED_ATTRIBUTE.match(node.attr):  # where its name ends
            found.append((node.end_lineno or 0, node.end_col_offset or 0, node.attr))
        for name in (
            node.id if isinstance(node, ast.Name) else None,
            node.arg if isinstance(node, ast.arg | ast.keyword) else None,
        ):
            if name is not None and _REFUSED_NAME.match(name):
                found.append((getattr(node, "lineno", 0), getattr(node, "col_offset", 0), name))
    return min(found)[2] if found else None


def checked_code(expression: str, current: Callable[[], str]) -> Any:
    """The compiled expression, or Refused naming the file (`current()`) and the expression."""
    text = expression.strip()
    tree = ast.parse(text, "<expression>", "eval")  # a SyntaxError stays xacro's usual error
    name = refused_name(tree)
    if name is not None:
        shown = text if len(text) <= SHOWN_EXPRESSION else text[:SHOWN_EXPRESSION] + "..."
        raise Refused(
            f"xacro file {current()}: expression '{shown}' is refused: it uses '{name}' (names and attributes starting "
            "with '_', and frame, generator, code and str.format attributes, reach Python's internals, which a xacro "
            "expression may not)"
        )
    return compile(ast.fix_missing_locations(_Sizes().visit(tree)), "<expression>", "eval")


class _TooLarge(Exception):
    pass


def _checked_binop(op: str, left: Any, right: Any) -> Any:
    """The operator, unless its result would be an integer or a sequence too large to build."""
    ints = isinstance(left, int) and isinstance(right, int)
    if op == "pow":
        if ints and right > 0 and abs(left) > 1 and right * abs(left).bit_length() > MAX_INT_BITS:
            raise _TooLarge(f"{left} ** {right} has more than {MAX_INT_BITS:,} bits")
        return left**right
    if op == "lshift":
        if ints and left and right > 0 and right + abs(left).bit_length() > MAX_INT_BITS:
            raise _TooLarge(f"{left} << {right} has more than {MAX_INT_BITS:,} bits")
        return left << right
    for sequence, count in ((left, right), (right, left)):
        if isinstance(sequence, str | bytes | list | tuple) and isinstance(count, int) and len(sequence) * count > MAX_ITEMS:
            raise _TooLarge(
                f"repeating a {type(sequence).__name__} of {len(sequence):,} items {count:,} times makes more than {MAX_ITEMS:,}"
            )
    return left * right


# What `$(eval ...)` may call besides arg(), find(), env(), optenv(), dirname() and math (xacro's own `python.` names).
_EVAL_BUILTINS: dict[str, Any] = {
    name: getattr(builtins, name)
    for name in "abs all any bool chr complex dict divmod enumerate filter float frozenset hash int isinstance issubclass "
    "len list map max min ord range repr reversed round set slice sorted str sum tuple zip".split()
}


class Sandbox:
    """Patches the imported xacro modules for one expansion (this process expands one file, then exits)."""

    def __init__(self, request: Mapping[str, Any]) -> None:
        self.file = str(request["file"])
        self.shown = str(request["shown"])
        self.packages = {name: Path(folder) for name, folder in request["packages"].items()}
        self.confinement = Confinement(Path(request["config_dir"]), tuple(Path(r) for r in request["read_roots"]), ())
        self.config_dir = Path(request["config_dir"])
        self.read: dict[str, None] = {}  # every file xacro opened, absolute, in order
        self.globs: dict[str, list[str]] = {}  # every include pattern and the files it matched

    def name(self, file: str | None) -> str:
        """A xacro file as the user knows it: as written in the config, relative to its folder, or absolute."""
        if file is None or file == self.file:
            return self.shown
        path = Path(file).resolve()
        return str(path.relative_to(self.config_dir)) if path.is_relative_to(self.config_dir) else str(path)

    def current(self) -> str:
        import xacro

        return self.name(xacro.filestack[-1] if xacro.filestack else None)

    def install(self) -> None:
        import xacro
        import xacro.substitution_args as substitution

        current = self.current
        self.original_parse = xacro.parse

        def safe_eval(expr: str, globals: dict[str, Any], locals: Mapping[str, Any] | None = None) -> Any:
            code = checked_code(expr, current)
            globals.update(__builtins__={_BINOP: _checked_binop})  # as xacro: no builtins, only the checked operator
            return eval(code, globals, locals)

        def eval_extension(s: str, context: dict[str, Any]) -> str:
            context.setdefault("arg", {})
            functions: dict[str, Any] = {
                "arg": lambda name: substitution.convert_value(substitution._eval_arg(name, args=context["arg"]), "auto"),
                "dirname": lambda: substitution._eval_dirname(context["filename"]),
            }
            functions.update(substitution._eval_dict)
            code = checked_code(s, current)
            allowed = {**_EVAL_BUILTINS, _BINOP: _checked_binop}
            return str(eval(code, {"__builtins__": allowed}, substitution._DictWrapper(context["arg"], functions)))

        def env(name: str) -> str:
            raise Refused(
                f"xacro file {current()}: $(env {name}) is refused: a xacro file may not copy the environment into the URDF "
                f"(plan prints it, run records it); pass the value as an argument: urdf.args {{{name}: VALUE}} and $(arg {name})"
            )

        def optenv(name: str, default: str = "") -> str:
            return default  # never the environment's value: the URDF must not depend on (or reveal) the runner's

        def vars_refused(*_: Any) -> Any:
            raise Refused(f"xacro file {current()}: python.vars() is refused (it reaches Python's internals by name)")

        xacro.safe_eval = safe_eval  # ${...}, and the expressions of xacro.load_yaml's !degrees-style tags
        substitution._eval = eval_extension  # $(eval ...)
        substitution._eval_env = env
        substitution._eval_optenv = optenv
        substitution._eval_find = self.find
        substitution._eval_dict.update(env=env, optenv=optenv, find=self.find)
        dict.__setitem__(xacro._global_symbols["python"], "vars", vars_refused)
        xacro.open = self.open  # parse() and load_yaml() open files through it
        xacro.glob = _Glob(self)  # xacro:include filename="dir/*.xacro"
        xacro.parse = self.parse  # the xacro file and every xacro:include

    def parse(self, inp: Any, filename: str | None = None) -> Any:
        """xacro's `parse`, after the file's prolog is checked: a DOCTYPE declaring entities or naming a DTD is refused
        before minidom reads it (minidom would expand the entities; ROS's URDF parser, reading xacro's output, none)."""
        import xacro

        from .xml_text import prolog_refusal  # here: the import lines are child_limits' and the sandbox's own

        if inp is None and filename is not None:
            path = os.path.join(xacro.root_dir, filename)
            try:
                with self.open(path, "rb") as file:
                    refusal = prolog_refusal(file.read())
            except OSError:  # a file that cannot be opened: xacro's own parse says so, as it always did
                refusal = None
            if refusal is not None:
                raise Refused(f"xacro file {self.name(path)}:{refusal}")
        return self.original_parse(inp, filename)

    def find(self, package: str) -> str:
        """`$(find PKG)` from the robot's package_paths, then ROS_PACKAGE_PATH / AMENT_PREFIX_PATH (no ament_index)."""
        if package in self.packages and self.packages[package].is_dir():
            return str(self.check(self.packages[package], f"$(find {package}) folder"))
        from .meshes import package_roots  # here: importing it costs the child 60 ms, and few xacros need it

        for root in package_roots(package):
            if root.is_dir():
                return str(self.check(root, f"$(find {package}) folder"))
        raise _UnknownPackage(package)

    def check(self, path: Path, what: str) -> Path:
        try:
            return self.confinement.check_read(path, what, None)
        except UserError as exc:
            raise Refused(f"xacro file {self.current()}: {exc.message}") from None

    def open(self, file: str, mode: str = "r", *args: Any, **kwargs: Any) -> Any:
        import xacro

        if set(mode) & set("wax+"):
            raise Refused(f"xacro file {self.current()}: xacro may not write {file}")
        stack = xacro.filestack or []
        reader = stack[-2] if len(stack) > 1 and stack[-1] == file else stack[-1] if stack else None
        try:
            self.confinement.check_read(Path(file), "included or loaded file", None)
        except UserError as exc:
            raise Refused(f"xacro file {self.name(reader)}: {exc.message}") from None
        self.read[os.path.abspath(file)] = None
        return open(file, mode, *args, **kwargs)


class _Glob:
    """xacro's `glob` module for `xacro:include` patterns: the folder before the first wildcard must be readable."""

    def __init__(self, sandbox: Sandbox) -> None:
        self.sandbox = sandbox

    def glob(self, pattern: str) -> list[str]:
        parts = Path(pattern).parts
        fixed = parts[: next((i for i, part in enumerate(parts) if glob.has_magic(part)), len(parts))]
        self.sandbox.check(Path(*fixed) if fixed else Path("."), "include pattern folder")
        matches = glob.glob(pattern)
        self.sandbox.globs[os.path.abspath(pattern)] = [os.path.abspath(match) for match in matches]
        return matches


def _chain(exc: BaseException) -> list[BaseException]:
    """`exc` and the exceptions it wraps (xacro's XacroException(exc=...)), or was raised while handling, inmost last."""
    chain: list[BaseException] = []
    current: BaseException | None = exc
    while current is not None and all(current is not seen for seen in chain):
        chain.append(current)
        context = None if current.__suppress_context__ else current.__context__
        current = getattr(current, "exc", None) or current.__cause__ or context
    return chain


def root_cause(exc: BaseException) -> BaseException:
    """The first refusal in the chain of `exc`, or the innermost exception."""
    chain = _chain(exc)
    return next((e for e in chain if isinstance(e, Refused | _UnknownPackage | _TooLarge)), chain[-1])


def ran_out(exc: BaseException, kind: type[BaseException]) -> bool:
    """Whether `kind` (RecursionError, MemoryError) is anywhere in the chain of `exc`."""
    return any(isinstance(e, kind) for e in _chain(exc))


def describe(exc: BaseException, sandbox: Sandbox) -> str:
    """The user's message for a failed expansion: what to fix, in which file."""
    import xacro

    cause = root_cause(exc)
    if isinstance(cause, Refused):
        return str(cause)
    if isinstance(cause, _UnknownPackage):
        package = cause.args[0]
        return f"xacro needs $(find {package}) in {sandbox.current()}: add it to this robot's package_paths ({package}: DIR)"
    undefined = re.search(r"Undefined substitution argument (\S+)", str(exc))
    if isinstance(cause, xacro.substitution_args.ArgException) or undefined:
        name = undefined.group(1) if undefined else cause.args[0]
        return f"xacro argument '{name}' has no value and no default in {sandbox.current()}: add it to urdf.args"
    if isinstance(cause, _TooLarge):
        return f"xacro file {sandbox.current()}: an expression is too large to evaluate: {cause}"
    if ran_out(exc, RecursionError):
        return f"xacro failed on {sandbox.current()}: expansion nested too deep (a macro or include that expands itself?)"
    text = " ".join(f"{type(exc).__name__}: {exc}".split())  # one line: xacro's messages span several
    return f"xacro failed on {sandbox.current()}: {text if len(text) < 2000 else text[:2000] + '...'}"


def main() -> None:
    """Entry point of the child process (see xacro_guard)."""
    request = json.load(sys.stdin)
    limit_this_process(request["limits"])
    import xacro

    sandbox = Sandbox(request)
    sandbox.install()
    answer: dict[str, Any] | None = None
    try:
        with contextlib.redirect_stdout(sys.stderr):  # xacro's messages are not the answer
            xacro.init_stacks(sandbox.file)
            document = xacro.parse(None, sandbox.file)
            xacro.process_doc(document, mappings=dict(request["args"]))
        answer = {"text": document.toprettyxml(indent="  "), "files": list(sandbox.read), "globs": list(sandbox.globs.items())}
    except MemoryError:
        pass  # answered below, once the frames holding the memory are gone
    except Exception as exc:  # whatever xacro raises is about the user's file
        if not ran_out(exc, MemoryError):  # xacro wraps it when an expression runs out
            answer = {"error": describe(exc, sandbox)}
    if answer is None:
        megabytes = request["limits"]["memory_bytes"] >> 20
        answer = {
            "error": f"xacro expansion of {sandbox.current()} needs more than {megabytes} MB of memory (a property or macro that grows without end?)"
        }
    json.dump(answer, sys.stdout)
    sys.stdout.flush()
