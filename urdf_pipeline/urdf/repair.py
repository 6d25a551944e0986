"""The URDF text handed to Rerun's loader: joint axes normalised, and what ROS tolerates but Rerun refuses repaired.

Rerun's loader (urdf-rs) uses a non-unit axis as given (wrong poses) and refuses a whole file over details ROS
(urdfdom) tolerates: an empty <texture/>, a material without a name, an <inertial> or a <visual> that urdfdom drops.
Here each such detail is made what ROS makes of it (the first of a repeated element, the element dropped) and said
in a note; a URDF that needs no repair is handed over byte for byte. Whatever Rerun's loader still refuses is a user
error found by `validate` (`rerun_loader_error`), not a crash in `run`; so is a tree deeper than it can walk
(`rerun_depth_problem`: it recurses once per level on a thread of Rust's default stack).
"""

from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .model import MOVING_TYPES, InvalidNumber, number, numbers, parse_root, unit_vector

# Elements Rerun's loader takes once; ROS reads the first and ignores the others.
_SINGLE = {
    "joint": ("origin", "parent", "child", "axis", "limit", "calibration", "dynamics", "mimic", "safety_controller"),
    "visual": ("origin", "geometry", "material"),
    "collision": ("origin", "geometry"),
    "inertial": ("origin", "mass", "inertia"),
    "material": ("color", "texture"),
}
RUST_STACK_ENV = "RUST_MIN_STACK"  # the stack, in bytes, of the threads Rust code starts (Rerun's loader among them)
RUST_DEFAULT_STACK = 2 << 20
STACK_PER_LEVEL = 2048  # bytes of that stack one tree level takes in Rerun's loader, with margin (measured: ~1.1 KB)
_GEOMETRY_ATTRIBUTES = {"box": ("size",), "cylinder": ("radius", "length"), "capsule": ("radius", "length"), "sphere": ("radius",)}


@dataclass
class _Repairs:
    changed: bool = False
    counts: Counter[str] = field(default_factory=Counter)
    first: dict[str, str] = field(default_factory=dict)

    def note(self, what: str, where: str) -> None:
        self.changed = True
        self.counts[what] += 1
        self.first.setdefault(what, where)

    def notes(self) -> tuple[str, ...]:
        return tuple(
            f"{what} ({count}x, first in {self.first[what]})" if count > 1 else f"{what} (in {self.first[what]})"
            for what, count in self.counts.items()
        )


def _valid(check: Callable[[], object]) -> bool:
    try:
        check()
    except InvalidNumber:
        return False
    return True


def _remove_repeats(parent: ET.Element, kind: str, where: str, repairs: _Repairs) -> None:
    for tag in _SINGLE.get(kind, ()):
        for extra in parent.findall(tag)[1:]:
            parent.remove(extra)
            repairs.note(f"a second <{tag}> in a <{kind}> removed (ROS reads the first)", where)


def _origin_ok(element: ET.Element) -> bool:
    origin = element.find("origin")
    return origin is None or _valid(lambda: (numbers(origin.get("xyz"), 3, 0.0), numbers(origin.get("rpy"), 3, 0.0)))


def _geometry_ok(element: ET.Element) -> bool:
    """What urdf-rs needs of a <geometry>: exactly one known shape with its attributes as numbers."""
    geometry = element.find("geometry")
    shapes = [] if geometry is None else list(geometry)
    if len(shapes) != 1:
        return False
    shape = shapes[0]
    if shape.tag == "mesh":
        scale = shape.get("scale")
        return bool(shape.get("filename")) and (scale is None or _valid(lambda: numbers(scale, 3, 1.0)))
    wanted = _GEOMETRY_ATTRIBUTES.get(shape.tag)
    if wanted is None:
        return False
    return all(shape.get(a) is not None for a in wanted) and _valid(
        lambda: [numbers(shape.get(a), 3, 0.0) if a == "size" else number(shape.get(a, "")) for a in wanted]
    )


def _inertial_ok(inertial: ET.Element) -> bool:
    mass, inertia = inertial.find("mass"), inertial.find("inertia")
    if mass is None or inertia is None or not _origin_ok(inertial):
        return False
    values = [mass.get("value", ""), *(inertia.get(key, "") for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))]
    return _valid(lambda: [number(value) for value in values])


def _repair_material(material: ET.Element, where: str, repairs: _Repairs) -> None:
    _remove_repeats(material, "material", where, repairs)
    texture = material.find("texture")
    if texture is not None and not texture.get("filename"):
        material.remove(texture)
        repairs.note("<texture> without filename removed", where)
    color = material.find("color")
    if color is not None and not _valid(lambda: numbers(color.get("rgba", ""), 4, 0.0)):
        material.remove(color)
        repairs.note("<color> whose rgba is not 4 numbers removed", where)


def _repair_link(link: ET.Element, repairs: _Repairs) -> None:
    where = f"link '{link.get('name', '')}'"
    for inertial in link.findall("inertial")[1:]:
        link.remove(inertial)
        repairs.note("a second <inertial> removed (ROS reads the first)", where)
    for inertial in link.findall("inertial"):
        _remove_repeats(inertial, "inertial", where, repairs)
        if not _inertial_ok(inertial):
            link.remove(inertial)  # not drawn; ROS drops a malformed one too
            repairs.note("malformed <inertial> removed (ROS drops it too)", where)
    for kind in ("visual", "collision"):
        for element in link.findall(kind):
            if not _repair_shape(element, kind, where, repairs):
                link.remove(element)
                repairs.note(f"<{kind}> with a malformed <geometry> or <origin> removed (ROS drops it too)", where)


def _repair_shape(element: ET.Element, kind: str, where: str, repairs: _Repairs) -> bool:
    """Repair a <visual> or <collision> in place; False when ROS would drop it."""
    _remove_repeats(element, kind, where, repairs)
    geometry = element.find("geometry")
    if geometry is not None:
        for extra in list(geometry)[1:]:
            geometry.remove(extra)
            repairs.note("a second shape in a <geometry> removed (ROS reads the first)", where)
    if not (_geometry_ok(element) and _origin_ok(element)):
        return False
    material = element.find("material")
    if material is not None and not material.get("name"):
        element.remove(material)
        repairs.note("<material> without name removed", where)
    elif material is not None:
        _repair_material(material, where, repairs)
    return True


def _repair_joint(joint: ET.Element, repairs: _Repairs) -> None:
    where = f"joint '{joint.get('name', '')}'"
    _remove_repeats(joint, "joint", where, repairs)
    axis = joint.find("axis")
    if axis is None:
        return
    if joint.get("type") not in MOVING_TYPES:
        if "xyz" not in axis.attrib:
            joint.remove(axis)  # unused by this joint type; Rerun's loader wants xyz on every <axis>
            repairs.note("<axis> without xyz removed from a joint that does not use it", where)
        return
    raw = numbers(axis.get("xyz"), 3, 0.0)  # parse_urdf_text accepted it: three numbers, not all zero
    unit = unit_vector(raw)
    if unit is not None and unit != raw:  # URDF semantics: the axis is normalised; Rerun's loader would use it as given
        axis.set("xyz", " ".join(repr(v) for v in unit))
        repairs.changed = True


def text_for_rerun(text: str, origin: str, root: ET.Element | None = None) -> tuple[str, tuple[str, ...]]:
    """The text to hand Rerun's loader and a note per kind of repair. `text` must have passed `parse_urdf_text`;
    `root`, its parsed XML from `parse_urdf`, is repaired in place (then it is not parsed again)."""
    robot = root if root is not None else parse_root(text, origin)[0]
    repairs = _Repairs()
    for material in robot.findall("material"):
        _repair_material(material, f"material '{material.get('name', '')}'", repairs)
    for link in robot.findall("link"):
        _repair_link(link, repairs)
    for joint in robot.findall("joint"):
        _repair_joint(joint, repairs)
    if not repairs.changed:
        return text, ()
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n", repairs.notes()


def rerun_depth_problem(depth: int) -> str | None:
    """Why Rerun's loader cannot walk a tree `depth` joints deep (root link to deepest leaf), or None. Its stack is
    Rust's default, or RUST_MIN_STACK when the person running the tool set it."""
    text = os.environ.get(RUST_STACK_ENV, "").strip()
    stack = int(text) if text.isdigit() and int(text) > 0 else RUST_DEFAULT_STACK
    limit = stack // STACK_PER_LEVEL
    if depth <= limit:
        return None
    needed = -(-depth * STACK_PER_LEVEL // (1 << 20)) << 20  # whole MiB
    return (
        f"Rerun's URDF loader walks the tree recursively, and with a {stack >> 10:,} KiB thread stack it would crash `run` "
        f"beyond about {limit:,} levels; the person running the tool can give it a larger stack: {RUST_STACK_ENV}={needed} (bytes)"
    )


def rerun_loader_error(text: str) -> str | None:
    """What Rerun's URDF loader says about `text`, or None when it loads (meshes are read later, when streamed)."""
    try:  # the compiled loader alone imports in milliseconds; `rerun.urdf` would import the whole SDK (~1 s)
        from rerun_bindings import _UrdfTreeInternal as load
    except ImportError:
        from rerun.urdf import UrdfTree as load  # type: ignore[assignment]
    with tempfile.TemporaryDirectory(prefix="urdf-pipeline-check-") as directory:
        path = Path(directory) / "robot.urdf"
        path.write_text(text, encoding="utf-8")
        try:
            load.from_file_path(str(path))
        except RuntimeError as exc:  # how the loader refuses a file; anything else is a bug and surfaces as one
            return str(exc).removeprefix("Failed to load URDF file: ")
    return None
