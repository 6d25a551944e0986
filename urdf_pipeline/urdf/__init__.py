"""The robot description: URDF text (a file, xacro in a bounded child process, robot_descriptions), read as XML with
what no URDF reader reads refused (xacro content, misplaced links and joints), the light model (joints, links, limits,
mimics), repairs for Rerun's loader, meshes, fixed chains, geometry.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .fixed_chain import NoFixedChain, compose_chain, find_fixed_chain
    from .geometry import Quaternion, Vector, normalized_quaternion, quaternion_from_rpy, quaternion_multiply
    from .load import LoadedUrdf, load_urdf_source
    from .meshes import garbage_meshes, package_roots, resolve_meshes, rewrite_mesh_uris
    from .model import Joint, UrdfModel, UrdfParseError, parse_urdf, parse_urdf_text, read_urdf
    from .repair import rerun_depth_problem, rerun_loader_error, text_for_rerun
    from .xacro_guard import XacroBudget
    from .xml_text import XacroContent

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
