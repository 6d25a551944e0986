"""'Did you mean': one rule for every misspelled name, so a suggestion appears only for a close match."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

CUTOFF = 0.75  # difflib ratio: a typo or two in a joint/frame name passes, another name of the robot does not


def closest(name: str, choices: Iterable[str]) -> str | None:
    """The choice closest to `name` (case-insensitive), if it is close enough to be the name meant."""
    by_folded = {choice.casefold(): choice for choice in sorted(choices, reverse=True)}
    close = difflib.get_close_matches(name.casefold(), list(by_folded), n=1, cutoff=CUTOFF)
    return by_folded[close[0]] if close else None


def did_you_mean(name: str, choices: Iterable[str]) -> str:
    """` (did you mean 'x'?)` to append to a message, or nothing."""
    close = closest(name, choices)
    return f" (did you mean '{close}'?)" if close is not None else ""
