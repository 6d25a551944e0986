"""What an MJCF model asks MuJoCo to build, counted while mjcf_files reads its XML, so a size bomb (a 1 KB file whose
nested `<replicate count="100">` make 10^8 bodies) is refused before MuJoCo compiles. The bounds (docs/urdf.md, MJCF)
are far above any robot's and low enough that MuJoCo compiles what passes in a few seconds and a few hundred MB.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from itertools import islice

from ..errors import UserError, Where, quoted, shown

MAX_NESTING = 200  # element levels, includes inlined
MAX_ELEMENTS = 10_000  # elements of the model MuJoCo builds: each copy a replicate makes, each generated point twice
MAX_NUMBERS = 1_000_000  # numbers written in attributes: inline mesh, flex and skin arrays, user data, keyframes
MAX_TEXTURE_PIXELS = 4096 * 4096  # texture width x height, summed; a cube or skybox texture counts its six faces
MAX_HFIELD_SAMPLES = 2048 * 2048  # height field nrow x ncol, summed
MAX_DECLARED = 1000  # <size nkey> and each <size nuser_*>: rows MuJoCo allocates per keyframe or per element
GENERATED = 2  # elements counted per point of a <composite> or <flexcomp> count (a body or vertex and its geom)
TOO_LARGE = "MuJoCo would need far more memory and time for it than any robot needs (a size bomb?)"
_TOKEN = re.compile(r"\S+")
_SHORT = 32  # attribute values this short are split; longer ones counted lazily, up to the bound


def _numbers(value: str, limit: int) -> int:
    """How many whitespace-separated words `value` holds, counted up to `limit` + 1 (a long array is never split)."""
    if len(value) < _SHORT:
        return len(value.split())
    return sum(1 for _ in islice(_TOKEN.finditer(value), limit + 1))


@dataclass(frozen=True)
class _Element:
    """One element being counted: what a refusal names."""

    tag: str
    attributes: dict[str, str]
    at: str  # FILE:LINE
    where: Where

    def refuse(self, name: str | None, what: str) -> UserError:
        shown_attribute = f" {shown(name)}={quoted(self.attributes[name], 60)}" if name else ""
        return UserError(f"MJCF file {self.at}: <{shown(self.tag)}{shown_attribute}> {what}; {TOO_LARGE}", self.where)

    def product(self, name: str) -> int:
        """The product of the numbers in an attribute (`count="10 10 1"`: 100), read as MuJoCo reads a count."""
        product = 1
        for word in self.attributes.get(name, "0").split()[:4]:
            try:
                number = float(word)
            except ValueError:
                number = math.nan
            if not math.isfinite(number) or number < 0:
                raise self.refuse(name, "is not a count MuJoCo can build (a whole number, at least 0)")
            product *= int(number)
        return product


@dataclass
class MjcfCounts:
    """One model's running counts (a `<model>` file has its own, added at each `<attach>`)."""

    elements: int = 0
    numbers: int = 0
    pixels: int = 0
    samples: int = 0
    models: list[MjcfCounts] = field(default_factory=list)  # the <model> files this one may attach
    attaches: list[tuple[int, str]] = field(default_factory=list)  # each <attach>: its multiplier, FILE:LINE

    def element(self, tag: str, attributes: dict[str, str], multiplier: int, nesting: int, at: str, where: Where) -> int:
        """Count one element (`multiplier` copies of it, `nesting` levels deep) and return the multiplier of its
        children; a UserError at `where`, naming `at` (FILE:LINE) and the element, when a bound is crossed."""
        element = _Element(tag, attributes, at, where)
        if nesting > MAX_NESTING:
            raise element.refuse(None, f"is nested more than {MAX_NESTING} elements deep")
        self._add_elements(element, None, multiplier, multiplier)
        for name, value in attributes.items():
            self.numbers += _numbers(value, MAX_NUMBERS) * multiplier
            if self.numbers > MAX_NUMBERS:
                raise element.refuse(name, f"brings the numbers written in the model's attributes to more than {MAX_NUMBERS:,}")
        sized = _SIZED.get(tag)
        return multiplier if sized is None else sized(self, element, multiplier)

    def _add_elements(self, element: _Element, name: str | None, count: int, multiplier: int) -> None:
        self.elements += count
        if self.elements > MAX_ELEMENTS:
            copies = f" (the replicates around it make {multiplier:,} copies of it)" if multiplier > 1 else ""
            made = " (with the points its count generates)" if name else copies
            raise element.refuse(
                name, f"brings the model to more than {MAX_ELEMENTS:,} elements after includes, replicates and attachments{made}"
            )

    def _generated(self, element: _Element, multiplier: int) -> int:
        if "count" in element.attributes:
            self._add_elements(element, "count", GENERATED * element.product("count") * multiplier, multiplier)
        return multiplier

    def _replicate(self, element: _Element, multiplier: int) -> int:
        inner = multiplier * element.product("count") if "count" in element.attributes else multiplier
        if inner > MAX_ELEMENTS:
            raise element.refuse(
                "count", f"makes {inner:,} copies of what it holds (with the replicates around it), more than {MAX_ELEMENTS:,}"
            )
        return inner

    def _texture(self, element: _Element, multiplier: int) -> int:
        if "width" in element.attributes or "height" in element.attributes:
            faces = 6 if element.attributes.get("type") in ("cube", "skybox") else 1
            self.pixels += faces * element.product("width") * element.product("height") * multiplier
            if self.pixels > MAX_TEXTURE_PIXELS:
                raise element.refuse("width", f"brings the model's texture pixels to more than {MAX_TEXTURE_PIXELS:,} (4096 x 4096)")
        return multiplier

    def _hfield(self, element: _Element, multiplier: int) -> int:
        if "nrow" in element.attributes or "ncol" in element.attributes:
            self.samples += element.product("nrow") * element.product("ncol") * multiplier
            if self.samples > MAX_HFIELD_SAMPLES:
                raise element.refuse("nrow", f"brings the model's height field samples to more than {MAX_HFIELD_SAMPLES:,} (2048 x 2048)")
        return multiplier

    def _numeric(self, element: _Element, multiplier: int) -> int:
        if "size" in element.attributes:
            self.numbers += element.product("size") * multiplier
            if self.numbers > MAX_NUMBERS:
                raise element.refuse("size", f"brings the numbers of the model's attributes and custom data to more than {MAX_NUMBERS:,}")
        return multiplier

    def _size(self, element: _Element, multiplier: int) -> int:
        for name in element.attributes:
            if (name == "nkey" or name.startswith("nuser_")) and element.product(name) > MAX_DECLARED:
                raise element.refuse(name, f"asks for more than {MAX_DECLARED:,} rows")
        return multiplier

    def _attach(self, element: _Element, multiplier: int) -> int:
        self.attaches.append((multiplier, element.at))
        return multiplier

    def image(self, tag: str, file: str, size: tuple[int, int], at: str, where: Where) -> None:
        """A texture's or height field's PNG file: its stated width x height, counted as the builtin ones are (a 400 KB
        PNG of 20000 x 20000 took MuJoCo 2.4 GB and 4 s to decode)."""
        pixels = size[0] * size[1]
        if tag == "texture":
            self.pixels += pixels
        else:
            self.samples += pixels
        bound = MAX_TEXTURE_PIXELS if tag == "texture" else MAX_HFIELD_SAMPLES
        if (self.pixels if tag == "texture" else self.samples) > bound:
            what = "texture pixels" if tag == "texture" else "height field samples"
            raise UserError(
                f"MJCF file {at}: <{tag} file={quoted(file)}> is a PNG of {size[0]:,} x {size[1]:,}, which brings the "
                f"model's {what} to more than {bound:,}; {TOO_LARGE}",
                where,
            )

    def attach_models(self, where: Where) -> None:
        """Each `<attach>` adds the largest model this one names (which one it attaches is MuJoCo's to decide)."""
        if not self.models:
            return
        largest = max(self.models, key=lambda model: (model.elements, model.numbers, model.pixels, model.samples))
        for multiplier, at in self.attaches:
            self.elements += largest.elements * multiplier
            self.numbers += largest.numbers * multiplier
            self.pixels += largest.pixels * multiplier
            self.samples += largest.samples * multiplier
            if (
                self.elements > MAX_ELEMENTS
                or self.numbers > MAX_NUMBERS
                or self.pixels > MAX_TEXTURE_PIXELS
                or self.samples > MAX_HFIELD_SAMPLES
            ):
                copies = f" (the replicates around it make {multiplier:,} copies)" if multiplier > 1 else ""
                raise UserError(
                    f"MJCF file {at}: <attach> brings the model, with the attached one{copies}, beyond its bounds "
                    f"({MAX_ELEMENTS:,} elements, {MAX_NUMBERS:,} numbers, {MAX_TEXTURE_PIXELS:,} texture pixels, "
                    f"{MAX_HFIELD_SAMPLES:,} height field samples); {TOO_LARGE}",
                    where,
                )


_SIZED: dict[str, Callable[[MjcfCounts, _Element, int], int]] = {
    "composite": MjcfCounts._generated,
    "flexcomp": MjcfCounts._generated,
    "replicate": MjcfCounts._replicate,
    "texture": MjcfCounts._texture,
    "hfield": MjcfCounts._hfield,
    "numeric": MjcfCounts._numeric,
    "size": MjcfCounts._size,
    "attach": MjcfCounts._attach,
}
