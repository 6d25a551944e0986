"""What is burned into a picture after the viewer drew it: the caption band at its bottom, and for `diff --render` the
old robot as a tinted ghost over the new one.

The band is part of the picture's size (camera.framing keeps the robot above it). Its text comes from input (file
names, segment ids, robot keys, joint and frame names): each line is made safe and cut to the picture's width (`fitted`).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from ..errors import LINE_LIMIT, shown
from .headless_viewer import Size, png_bytes

if TYPE_CHECKING:
    from PIL import ImageFont

BAND_COLOUR = (24, 24, 27)
RULE_COLOUR = (70, 70, 76)
TITLE_COLOUR = (240, 240, 240)
TEXT_COLOUR = (180, 180, 186)
MAX_BAND_SHARE = 0.3  # of the picture's height, whatever the number of lines asked for
GHOST_TINT = np.array([70.0, 190.0, 255.0])  # the old robot in a blue no robot of the examples has
GHOST_ALPHA = 0.45
DIFFERENT = 24  # a channel this far from the background (or from the new picture) is the robot's


def font_size(size: Size) -> int:
    return max(10, min(size.height // 34, size.width // 48))


def line_height(size: Size) -> int:
    return round(font_size(size) * 1.25)


def _padding(size: Size) -> int:
    return max(4, font_size(size) // 2)


def lines_that_fit(size: Size, wanted: int) -> int:
    """How many of `wanted` caption lines the band holds (at least one; the band stays within MAX_BAND_SHARE)."""
    room = int(size.height * MAX_BAND_SHARE) - 2 * _padding(size)
    return max(1, min(wanted, room // line_height(size)))


def band_height(size: Size, lines: int) -> int:
    """The band's height in pixels for `lines` lines of caption (as many as fit)."""
    return lines_that_fit(size, lines) * line_height(size) + 2 * _padding(size)


@lru_cache(maxsize=8)
def _font(pixels: int) -> ImageFont.FreeTypeFont | ImageFont.ImageFont:
    from PIL import ImageFont

    return ImageFont.load_default(size=pixels)  # FreeType's Aileron, bundled with Pillow >= 10.1


@lru_cache(maxsize=4096)
def _glyph(pixels: int, character: str) -> bytes:
    """How the font draws one character (its pixels): the same as for U+10FFFD means it has no glyph for it."""
    from PIL import Image, ImageDraw

    image = Image.new("L", (pixels * 3, pixels * 2))
    ImageDraw.Draw(image).text((pixels // 2, pixels // 4), character, fill=255, font=_font(pixels))
    return image.tobytes()


def drawable(text: str, pixels: int) -> str:
    """`text` with each character the font has no glyph for written as its escape (`\\u00e9`): Pillow's bundled font
    covers ASCII and a little punctuation, and a box in place of a letter would hide which name it is."""
    missing = _glyph(pixels, "\U0010fffd")
    return "".join(
        c if c.isascii() or _glyph(pixels, c) != missing else f"\\u{ord(c):04x}" if ord(c) < 0x10000 else f"\\U{ord(c):08x}" for c in text
    )


def fitted(text: str, width: float, font: ImageFont.FreeTypeFont | ImageFont.ImageFont, pixels: int) -> str:
    """`text` as one safe line (errors.shown, then `drawable`), cut in its middle with `…` where it is wider than `width`
    pixels: both ends stay (a config's name and the time after it, an edge and how far it moved)."""
    line = drawable(shown(text, LINE_LIMIT), pixels)
    if font.getlength(line) <= width:
        return line
    low, high = 0, len(line)
    while low < high:  # the most characters kept, half from each end, that fit with the ellipsis
        middle = (low + high + 1) // 2
        if font.getlength(_cut(line, middle)) <= width:
            low = middle
        else:
            high = middle - 1
    return _cut(line, low)


def _cut(line: str, keep: int) -> str:
    head, tail = (keep + 1) // 2, keep // 2
    return line[:head] + "…" + (line[len(line) - tail :] if tail else "")


def burn_caption(png: bytes, lines: Sequence[str], band: int) -> bytes:
    """The picture with its bottom `band` pixels replaced by the caption: the first line bright, the rest dimmer;
    lines beyond what the band holds are left out (the caller says `+N more` itself)."""
    from PIL import Image, ImageDraw

    with Image.open(io.BytesIO(png)) as opened:
        image = opened.convert("RGB")
    size = Size(image.width, image.height)
    font, step, pad = _font(font_size(size)), line_height(size), _padding(size)
    top = image.height - band
    draw = ImageDraw.Draw(image)
    draw.rectangle((0, top, image.width, image.height), fill=BAND_COLOUR)
    draw.line((0, top, image.width, top), fill=RULE_COLOUR)
    room = max(1, (band - 2 * pad) // step)
    for index, line in enumerate(list(lines)[:room]):
        text = fitted(line, image.width - 2 * pad, font, font_size(size))
        draw.text((pad, top + pad + index * step), text, fill=TITLE_COLOUR if index == 0 else TEXT_COLOUR, font=font)
    return png_bytes(image)


def changes_caption(title: str, changes: Sequence[str], size: Size) -> list[str]:
    """A title and as many changes as the band holds; the last line says `+N more` when some are left out."""
    room = lines_that_fit(size, 1 + max(len(changes), 1)) - 1
    if not changes:
        return [title, "no semantic difference: both draw alike"]
    if len(changes) <= room:
        return [title, *changes]
    shown_changes = list(changes[: max(room - 1, 0)])
    more = len(changes) - len(shown_changes)
    return [title, *shown_changes, f"+{more} more change(s): see the report"]


def ghost_over(new: bytes, old: bytes, background: bytes) -> bytes:
    """`new` opaque, with the old robot blended over it, tinted, where the old picture shows a robot (it differs from
    the background) and differs from the new one: parts that did not move stay as the new picture draws them."""
    from PIL import Image

    pictures = [np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.float64) for png in (new, old, background)]
    now, before, empty = pictures
    if not (now.shape == before.shape == empty.shape):
        raise ValueError(f"pictures of different sizes: {now.shape}, {before.shape}, {empty.shape}")
    robot = np.abs(before - empty).max(axis=2) > DIFFERENT
    moved = robot & (np.abs(before - now).max(axis=2) > DIFFERENT)
    light = before.mean(axis=2, keepdims=True) / 255.0
    tinted = GHOST_TINT * (0.45 + 0.55 * light)
    out = np.where(moved[..., None], (1 - GHOST_ALPHA) * now + GHOST_ALPHA * tinted, now)
    return png_bytes(Image.fromarray(np.clip(out.round(), 0, 255).astype(np.uint8), "RGB"))
