"""The robot model stream: meshes and static joint transforms from Rerun's UrdfTree."""

from __future__ import annotations

import atexit
import shutil
import tempfile
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from ..plan import RobotPlan

if TYPE_CHECKING:
    from collections.abc import Callable

    from rerun.chunk import Chunk, LazyChunkStream
    from rerun.urdf import UrdfTree


_TREES: dict[tuple[str, str, str, str], UrdfTree] = {}


def cached_tree(robot: RobotPlan) -> UrdfTree:
    """UrdfTree from the plan's URDF text (mesh URIs already absolute), parsed once per process: a worker writing
    hundreds of segments of one robot parses its URDF once."""
    from rerun.urdf import UrdfTree

    key = (robot.key, robot.urdf_text, robot.entity_path_prefix, robot.frame_prefix)
    if key not in _TREES:
        urdf_file = _tree_directory() / f"{robot.key}.urdf"
        urdf_file.write_text(robot.urdf_text, encoding="utf-8")
        _TREES[key] = UrdfTree.from_file_path(
            urdf_file,
            entity_path_prefix=robot.entity_path_prefix.strip("/"),
            frame_prefix=robot.frame_prefix or None,
            static_transform_entity_path=robot.static_transform_entity,
        )
    return _TREES[key]


@cache
def _tree_directory() -> Path:
    """URDF files of cached trees live as long as the process (the trees may read them again)."""
    directory = Path(tempfile.mkdtemp(prefix="urdf-pipeline-trees-"))
    atexit.register(shutil.rmtree, directory, True)
    return directory


def robot_model_stream(robot: RobotPlan, tree: UrdfTree) -> LazyChunkStream:
    # include_joint_transforms=True: with False, Rerun logs no fixed-joint edges at all.
    stream = tree.stream(include_joint_transforms=True)
    if not robot.keep_collisions:
        _assert_filter_matches(robot, tree)
        stream = stream.drop(content=robot.collision_filter)
    if robot.appearance is not None:
        stream = stream.flat_map(recolor(robot.appearance))
    return stream


# The colour component of each geometry archetype UrdfTree emits, by a component its chunks always carry.
_COLOR_OF = {
    "Asset3D:blob": ("Asset3D", "albedo_factor"),
    "Mesh3D:vertex_positions": ("Mesh3D", "albedo_factor"),
    "Boxes3D:half_sizes": ("Boxes3D", "colors"),
    "Cylinders3D:lengths": ("Cylinders3D", "colors"),
    "Ellipsoids3D:half_sizes": ("Ellipsoids3D", "colors"),
    "Capsules3D:lengths": ("Capsules3D", "colors"),
}


def recolor(rgba: tuple[float, float, float, float]) -> Callable[[Chunk], list[Chunk]]:
    """`appearance:`: each static geometry chunk followed by one static chunk of its colour (RGBA, alpha < 1 drawn
    translucent) on the same entity. Static data keeps the latest row per component, so the colour replaces the URDF's
    material; a chunk per visual (links, not rows), never a row loop, and the geometry itself is passed through."""
    import rerun as rr
    from rerun.chunk import Chunk

    packed = [round(channel * 255) for channel in rgba]

    def with_color(chunk: Chunk) -> list[Chunk]:
        if not chunk.is_static:
            return [chunk]
        names = set(chunk.to_record_batch().schema.names)
        for component, (archetype, field) in _COLOR_OF.items():
            if component in names:
                columns = getattr(rr, archetype).columns(**{field: [packed]})
                return [chunk, Chunk.from_columns(chunk.entity_path, [], columns)]
        return [chunk]

    return with_color


def _assert_filter_matches(robot: RobotPlan, tree: UrdfTree) -> None:
    """A drop filter that matches nothing fails silently; check it against the paths UrdfTree really emits."""
    prefix = robot.collision_filter.removesuffix("**")
    for link in robot.links:
        for path in tree.get_collision_geometry_paths(link):
            if not ("/" + path.lstrip("/")).startswith(prefix):
                raise AssertionError(f"collision filter {robot.collision_filter} misses {path}")
