"""What `pip install` of a wheel gets: every package, the example configs, floors that mean something."""

from __future__ import annotations

import re
import tomllib
from importlib.metadata import requires

from ..conftest import REPO

PYPROJECT = tomllib.loads((REPO / "pyproject.toml").read_text())


def test_every_package_folder_is_in_the_wheel() -> None:
    folders = {
        ".".join(init.parent.relative_to(REPO).parts)
        for init in (REPO / "urdf_pipeline").rglob("__init__.py")
        if "__pycache__" not in init.parts
    }
    listed = set(PYPROJECT["tool"]["setuptools"]["packages"])
    assert listed == folders | {"urdf_pipeline.data", "urdf_pipeline.example_configs"}  # data: the schema
    assert PYPROJECT["tool"]["setuptools"]["package-dir"] == {"urdf_pipeline.example_configs": "configs"}
    assert "*.yaml" in PYPROJECT["tool"]["setuptools"]["package-data"]["urdf_pipeline.example_configs"]


def _floor(requirement: str) -> tuple[int, ...]:
    match = re.search(r">=\s*([\d.]+)", requirement)
    assert match, f"{requirement} has no floor"
    return (*(int(part) for part in match.group(1).split(".")), 0, 0)[:3]


def _named(requirements: list[str], name: str) -> str:
    return next(r for r in requirements if re.split(r"[\s<>=!~;\[]", r, maxsplit=1)[0].lower() == name)


def test_floors_are_at_least_what_the_pinned_rerun_sdk_requires() -> None:
    ours = PYPROJECT["project"]["dependencies"]
    rerun = [r for r in requires("rerun-sdk") or [] if "extra ==" not in r]
    for name in ("numpy", "pyarrow"):
        assert _floor(_named(ours, name)) >= _floor(_named(rerun, name)), (
            f"{name}: {_named(ours, name)} vs rerun-sdk's {_named(rerun, name)}"
        )
    assert _named(ours, "rerun-sdk") == "rerun-sdk==0.41.*"


def test_the_project_says_its_license_home_and_version_source() -> None:
    project = PYPROJECT["project"]
    assert (REPO / project["license-files"][0]).read_text().lstrip().startswith("Apache License")
    assert project["license"] == "Apache-2.0" and project["urls"]["Source"].startswith("https://github.com/")
    assert project["dynamic"] == ["version"]
    assert PYPROJECT["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "urdf_pipeline.package.__version__"}
