"""The caption band and the diff's ghost, with Pillow alone: a hostile name never breaks the layout, the band never
touches what is above it, the ghost marks where the old robot was and nothing else."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image, ImageFont

from urdf_pipeline.render.captions import (
    BAND_COLOUR,
    band_height,
    burn_caption,
    changes_caption,
    drawable,
    fitted,
    font_size,
    ghost_over,
    line_height,
    lines_that_fit,
)
from urdf_pipeline.render.headless_viewer import Size

HOSTILE = [
    "demo\n::error::forged.yaml",  # a newline and a workflow command
    "right\u202eto\u202cleft \x1b[31mred\x1b[0m\ttab\r",  # a bidi override, an ANSI colour, a tab, a carriage return
    "a" * 5000,  # very long
    "bras_gauche_é 日本語 🤖",  # letters the bundled font does not have
    "",
]


def _png(width: int, height: int, colour: tuple[int, int, int] = (13, 13, 13)) -> bytes:
    rng = np.random.default_rng(0)
    pixels = np.clip(rng.normal(colour, 20, size=(height, width, 3)), 0, 255).astype(np.uint8)  # noisy: any change shows
    buffer = io.BytesIO()
    Image.fromarray(pixels, "RGB").save(buffer, format="PNG")
    return buffer.getvalue()


def _pixels(png: bytes) -> np.ndarray:
    with Image.open(io.BytesIO(png)) as image:
        return np.asarray(image.convert("RGB"), dtype=np.int16)


def test_pillows_bundled_font_scales() -> None:
    """ImageFont.load_default(size=...) is FreeType (Pillow >= 10.1 with FreeType): no font is downloaded."""
    small, large = ImageFont.load_default(size=10), ImageFont.load_default(size=30)
    assert isinstance(small, ImageFont.FreeTypeFont)
    assert large.getlength("rest pose") > 2.5 * small.getlength("rest pose")


@pytest.mark.parametrize("size", [Size(320, 240), Size(1024, 768), Size(64, 48)])
@pytest.mark.parametrize("name", HOSTILE)
def test_a_hostile_name_stays_in_its_band(size: Size, name: str) -> None:
    band = band_height(size, 2)
    picture = _png(size.width, size.height)
    captioned = burn_caption(picture, [f"{name} · rest pose", f"robot {name}"], band)
    before, after = _pixels(picture), _pixels(captioned)
    assert after.shape == before.shape, "the picture keeps its size"
    assert np.array_equal(after[: size.height - band], before[: size.height - band]), "nothing drawn above the band"
    below = after[size.height - band + 1 :]
    assert (below != BAND_COLOUR).any(axis=2).any(), "the caption is written"
    assert (below == BAND_COLOUR).all(axis=2).mean() > 0.5, "on the band's own colour"


@pytest.mark.parametrize("name", HOSTILE)
def test_a_caption_line_is_one_safe_line_that_fits(name: str) -> None:
    pixels = 14
    font = ImageFont.load_default(size=pixels)
    line = fitted(f"segment {name} at frame_index 3", 300, font, pixels)
    assert font.getlength(line) <= 300
    assert not any(ord(c) < 0x20 or 0x7F <= ord(c) <= 0x9F or 0x202A <= ord(c) <= 0x202E for c in line), repr(line)
    assert drawable(line, pixels) == line, "every character drawn is one the font has"


def test_letters_the_font_lacks_are_written_as_escapes() -> None:
    assert drawable("bras_é · 日…", 14) == "bras_\\u00e9 · \\u65e5…"
    assert drawable("plain ascii: [0.4, 0, 0.5] -> ok", 14) == "plain ascii: [0.4, 0, 0.5] -> ok"


def test_the_band_grows_with_lines_up_to_a_share_of_the_picture() -> None:
    size = Size(1024, 768)
    assert font_size(size) >= 16 and font_size(Size(320, 240)) >= 10
    assert band_height(size, 1) < band_height(size, 2) < band_height(size, 5)
    assert band_height(size, 100) <= 0.3 * size.height
    assert lines_that_fit(Size(320, 240), 100) * line_height(Size(320, 240)) <= 0.3 * 240


def test_changes_are_listed_as_far_as_they_fit_then_counted() -> None:
    small, large = Size(320, 240), Size(1024, 768)
    changes = [f"edge world -> link{i}: moved {i}.0 mm, 0.00 deg" for i in range(12)]
    caption = changes_caption("old -> new", changes, small)
    assert caption[0] == "old -> new" and len(caption) == lines_that_fit(small, 13)
    assert caption[-1] == f"+{12 - (len(caption) - 2)} more change(s): see the report"
    assert caption[1:-1] == changes[: len(caption) - 2]
    assert changes_caption("t", changes[:2], large) == ["t", *changes[:2]], "all of them when they fit"
    assert changes_caption("t", [], large) == ["t", "no semantic difference: both draw alike"]


def _square(base: bytes, left: int, colour: tuple[int, int, int]) -> bytes:
    pixels = _pixels(base).astype(np.uint8)
    pixels[20:60, left : left + 40] = colour
    buffer = io.BytesIO()
    Image.fromarray(pixels, "RGB").save(buffer, format="PNG")
    return buffer.getvalue()


def test_the_ghost_marks_where_the_old_robot_was_and_nothing_else() -> None:
    """Old: a square at the left and one in the middle; new: the middle one, and one at the right. The ghost shows at
    the left only: the middle did not move, the right is the new robot as drawn."""
    background = _png(200, 100)
    old = _square(_square(background, 10, (220, 220, 220)), 80, (200, 180, 40))
    new = _square(_square(background, 150, (220, 220, 220)), 80, (200, 180, 40))
    out, before, now, empty = (_pixels(p) for p in (ghost_over(new, old, background), old, new, background))
    assert np.array_equal(out[:, 60:], now[:, 60:]), "unchanged and new parts as the new picture draws them"
    ghost = out[20:60, 10:50]
    assert (ghost[..., 2] > ghost[..., 0] + 40).all(), "the old robot's place is tinted blue"
    assert (np.abs(ghost - empty[20:60, 10:50]).max(axis=2) > 24).all() and (ghost.mean(axis=2) < before[20:60, 10:50].mean(axis=2)).all()
    assert np.array_equal(out[:20], now[:20]) and np.array_equal(out[60:], now[60:]), "the background left alone"
    with pytest.raises(ValueError, match="different sizes"):
        ghost_over(new, _png(100, 100), background)


def test_a_long_line_is_cut_in_its_middle_so_both_ends_stay() -> None:
    font = ImageFont.load_default(size=14)
    line = fitted("segment " + "y" * 400 + " · frame_index 42", 300, font, 14)
    assert line.startswith("segment y") and line.endswith("frame_index 42") and "…" in line
    assert font.getlength(line) <= 300
