"""The robot description: URDF text (a file, xacro in a bounded child process, robot_descriptions), the light model
(joints, links, limits, mimics), repairs for Rerun's loader, meshes, fixed chains, geometry.
May import: the top-level base (errors, plan, confine) and config (for locations)."""
