"""Matching a source's names to URDF joints by name similarity, for init's pre-filled map."""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass

MATCH_CUTOFF = 0.75  # normalised names at least this similar (difflib ratio) are pre-matched, for review


@dataclass(frozen=True)
class NameKey:
    side: str  # "left", "right" or ""
    tokens: tuple[str, ...]

    @property
    def numbers(self) -> tuple[str, ...]:
        return tuple(t for t in self.tokens if t.isdigit())


_CAMEL = re.compile(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])")
_JOINT_WORDS = {"joint", "jnt", "j"}
_SIDES = {"l": "left", "left": "left", "lft": "left", "r": "right", "right": "right", "rgt": "right", "rt": "right"}


def name_tokens(name: str) -> list[str]:
    """`kLeftShoulderPitch` -> left shoulder pitch; `wrist_1_joint` -> wrist 1 joint; `Joint8.0` -> joint 8 0."""
    name = re.sub(r"^k(?=[A-Z])", "", name)  # Unitree's constant style: kLeftElbow
    name = _CAMEL.sub("_", name)
    return [piece for part in re.split(r"[^A-Za-z0-9]+", name.lower()) if part for piece in re.findall(r"[a-z]+|[0-9]+", part)]


def name_key(name: str) -> NameKey:
    """Lowercase tokens without joint words (`joint_`, `_joint`, `j1`), the side (`left_`, `l_`, `_r`) apart."""
    tokens = name_tokens(name)
    kept = [t for t in tokens if t not in _JOINT_WORDS] or tokens
    side = ""
    if len(kept) > 1 and kept[0] in _SIDES:
        side, kept = _SIDES[kept[0]], kept[1:]
    elif len(kept) > 1 and kept[-1] in _SIDES:
        side, kept = _SIDES[kept[-1]], kept[:-1]
    return NameKey(side, tuple(kept))


def _strip_common(keys: list[NameKey]) -> list[NameKey]:
    """Drop the leading and trailing tokens every name of a list shares (`panda` of `panda_joint1`..`panda_finger_joint1`,
    `pos` of `shoulder_pan.pos`..`gripper.pos`), as long as every name keeps one."""
    if len(keys) < 2:
        return keys
    for end in (0, -1):
        while all(len(k.tokens) > 1 for k in keys) and len({k.tokens[end] for k in keys}) == 1 and not keys[0].tokens[end].isdigit():
            keys = [NameKey(k.side, k.tokens[1:] if end == 0 else k.tokens[:-1]) for k in keys]
    return keys


def similarity(a: NameKey, b: NameKey) -> float:
    """0..1: the mean of the character and the word similarity (difflib) of the normalised names. Different sides, or
    different numbers (wrist_1 vs wrist_2), never match; numbers on one side only are left out; one side unknown costs 10 %."""
    if a.side and b.side and a.side != b.side:
        return 0.0
    if a.numbers and b.numbers and a.numbers != b.numbers:
        return 0.0
    words_a, words_b = list(a.tokens), list(b.tokens)
    if not (a.numbers and b.numbers):
        words_a = [t for t in words_a if not t.isdigit()] or words_a
        words_b = [t for t in words_b if not t.isdigit()] or words_b
    chars = difflib.SequenceMatcher(None, "_".join(words_a), "_".join(words_b)).ratio()
    words = difflib.SequenceMatcher(None, words_a, words_b).ratio()
    return (chars + words) / 2 * (0.9 if bool(a.side) != bool(b.side) else 1.0)


@dataclass(frozen=True)
class Match:
    source_name: str
    joint: str
    score: float


def match_names(source_names: list[str], joints: list[str]) -> list[Match]:
    """One-to-one pre-matching, best pairs first (identical names before equal scores), in source order.

    Each name is compared as is and without the leading and trailing tokens all names of its side share (`panda_` in
    `panda_joint1`..`panda_finger_joint1`, `.pos` in `shoulder_pan.pos`..`gripper.pos`); the best comparison counts.
    """
    source_keys = list(zip([name_key(n) for n in source_names], _strip_common([name_key(n) for n in source_names]), strict=True))
    joint_keys = list(zip([name_key(j) for j in joints], _strip_common([name_key(j) for j in joints]), strict=True))
    pairs = []
    for i, name in enumerate(source_names):
        for k, joint in enumerate(joints):
            score = 1.0 if name == joint else max(similarity(a, b) for a in set(source_keys[i]) for b in set(joint_keys[k]))
            if score >= MATCH_CUTOFF:
                pairs.append((-round(score, 6), name != joint, i, k))
    used_sources: set[int] = set()
    used_joints: set[int] = set()
    matches: dict[int, Match] = {}
    for negative, _, i, k in sorted(pairs):
        if i not in used_sources and k not in used_joints:
            used_sources.add(i)
            used_joints.add(k)
            matches[i] = Match(source_names[i], joints[k], -negative)
    return [matches[i] for i in sorted(matches)]
