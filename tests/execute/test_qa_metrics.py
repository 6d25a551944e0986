"""The QA metrics core: every number equals a plain numpy reference on the whole arrays, any split into blocks gives
the same numbers, and on teleoperation-like synthetic data each planted fault gets exactly its flag on exactly its
segment while clean data with sensor noise gets none (at 30 fps and at 1 kHz)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from urdf_pipeline.execute.qa_metrics import JERK_PRECISION, NOMINAL_STEPS, SegmentMetrics, SegmentQa, by_joint, segment_flags
from urdf_pipeline.plan import QaPlan

DEG = math.pi / 180
NOISE = 0.05 * DEG
NAMES = ("j1", "j2", "j3", "j4", "j5", "finger")
ANGULAR = {name: name != "finger" for name in NAMES}
KINDS = [ANGULAR[name] for name in NAMES]
QA = QaPlan()
LOWER = np.array([-3.0] * 5 + [-0.001])  # the limits with their slack
UPPER = np.array([3.0] * 5 + [0.05])


@dataclass
class Episode:
    values: np.ndarray
    times: np.ndarray | None  # seconds (float64) or nanoseconds (int64)
    fps: float | None


def teleoperation(rng: np.random.Generator, rows: int, fps: float, moving: bool = True) -> np.ndarray:
    """Smooth sinusoids (a few tens of degrees at 0.1-0.5 Hz; the finger a few cm) plus 0.05 deg of sensor noise."""
    t = np.arange(rows)[:, None] / fps
    amplitude = np.concatenate([rng.uniform(10, 40, 5) * DEG, [0.015]]) if moving else np.zeros(6)
    frequency = rng.uniform(0.1, 0.5, 6)
    phase = rng.uniform(0, 2 * math.pi, 6)
    centre = np.concatenate([rng.uniform(-0.5, 0.5, 5), [0.02]])
    noise = rng.normal(0, 1, (rows, 6)) * np.concatenate([[NOISE] * 5, [0.00005]])
    return centre + amplitude * np.sin(2 * math.pi * frequency * t + phase) + noise


def feed(episode: Episode, block: int, segment_id: str = "s", qa: QaPlan = QA) -> SegmentMetrics:
    metrics = SegmentQa(
        segment_id,
        NAMES,
        by_joint(KINDS, qa.static_velocity.angle, qa.static_velocity.length),
        LOWER,
        UPPER,
        fps=episode.fps,
        gap_seconds=qa.gap_seconds,
        gap_steps=qa.gap_steps,
    )
    for start in range(0, episode.values.shape[0], block):
        times = None if episode.times is None else episode.times[start : start + block]
        metrics.add(episode.values[start : start + block], times)
    return metrics.finish()


def reference(episode: Episode, qa: QaPlan = QA) -> dict[str, object]:
    """The metrics computed plainly on the whole arrays."""
    x, times, fps = episode.values, episode.times, episode.fps
    rows = x.shape[0]
    if times is None:
        assert fps is not None
        steps = np.full(rows - 1, 1 / fps)
    elif times.dtype.kind == "i":
        steps = np.diff(times).astype(np.float64) / 1e9
    else:
        steps = np.diff(times)
    with np.errstate(invalid="ignore", divide="ignore"):
        step = np.where(steps > 0, steps, np.nan)[:, None]
        velocity = np.diff(x, axis=0) / step
        jerk = np.diff(np.diff(velocity, axis=0) / step[1:], axis=0) / step[2:]
    static = by_joint(KINDS, qa.static_velocity.angle, qa.static_velocity.length)
    joints = {}
    for j, name in enumerate(NAMES):
        speed = np.abs(velocity[:, j])
        speed = speed[np.isfinite(speed)]
        size = np.abs(jerk[:, j])
        finite = np.isfinite(size)
        joints[name] = {
            "max_abs_velocity": float(speed.max()),
            "p95_abs_jerk": float(np.percentile(size[finite], 95)),
            "max_abs_jerk": float(size[finite].max()),
            "max_jerk_row": int(np.nanargmax(np.where(finite, size, -np.inf))) + 3,
            "static_fraction": float((speed < static[j]).sum() / speed.size),
            "nan": int((~np.isfinite(x[:, j])).sum()),
            "limits": int((np.isfinite(x[:, j]) & ((x[:, j] < LOWER[j]) | (x[:, j] > UPPER[j]))).sum()),
        }
    forward = steps[np.isfinite(steps) & (steps > 0)]
    nominal = 1 / fps if fps else float(np.median(forward[:NOMINAL_STEPS]))
    tolerance = qa.gap_seconds if qa.gap_seconds is not None else qa.gap_steps * nominal
    if times is None:
        duration = (rows - 1) / fps
    elif times.dtype.kind == "i":
        duration = float(times[-1] - times[0]) / 1e9
    else:
        duration = float(times[-1] - times[0])
    timing = {  # without timestamps (frames / fps) there is no step to judge
        "max_gap_s": float(np.nanmax(steps)) if times is not None else None,
        "gaps": int((forward > tolerance).sum()),
        "order_violations": int((~(steps > 0)).sum()),
        "nominal_step_s": nominal,
    }
    return {"rows": rows, "duration_s": duration, "joints": joints, "timing": timing}


def assert_matches(found: SegmentMetrics, expected: dict[str, object]) -> None:
    assert found.rows == expected["rows"]
    assert found.duration_s == pytest.approx(expected["duration_s"], rel=1e-12)
    timing = expected["timing"]
    assert isinstance(timing, dict)
    assert found.timing.max_gap_s == timing["max_gap_s"]
    assert found.timing.gaps == timing["gaps"] and found.timing.order_violations == timing["order_violations"]
    assert found.timing.nominal_step_s == pytest.approx(timing["nominal_step_s"], rel=1e-12)
    joints = expected["joints"]
    assert isinstance(joints, dict)
    for name, want in joints.items():
        got = found.joints[name]
        assert got.max_abs_velocity == want["max_abs_velocity"], name
        assert got.max_abs_jerk == want["max_abs_jerk"] and got.max_jerk_row == want["max_jerk_row"], name
        assert got.static_fraction == want["static_fraction"], name
        assert got.nan == want["nan"] and got.limits == want["limits"], name
        assert got.p95_abs_jerk == pytest.approx(want["p95_abs_jerk"], rel=JERK_PRECISION), name


def rough_episode(rng: np.random.Generator, timeline: str, fps: float = 30.0) -> Episode:
    """Noisy motion with every kind of trouble inside: NaNs, values beyond the limits, a repeated and a backwards
    timestamp, a gap, and uneven steps."""
    rows = 2500
    x = teleoperation(rng, rows, fps)
    x[100:103, 1] = np.nan
    x[400, 0] = 3.5
    x[900:905, 5] = 0.06
    seconds = np.arange(rows) / fps + rng.uniform(-0.06, 0.06, rows) / fps
    seconds[1500:] += 0.2  # a gap
    seconds[1700] = seconds[1699]  # a repeated timestamp
    seconds[2000] = seconds[1999] - 0.01  # a backwards one
    if timeline == "fps":
        return Episode(x, None, fps)
    if timeline == "ns":
        return Episode(x, (seconds * 1e9).astype(np.int64) + 1_700_000_000_000_000_000, None)
    return Episode(x, seconds, None)


@pytest.mark.parametrize("fps", [30.0, 1000.0])
@pytest.mark.parametrize("timeline", ["seconds", "ns", "fps"])
def test_every_number_equals_the_numpy_reference(timeline: str, fps: float) -> None:
    episode = rough_episode(np.random.default_rng(7), timeline, fps)
    assert_matches(feed(episode, 1000), reference(episode))


def test_memory_is_bounded_by_one_block_not_the_episode() -> None:
    """The accumulators' state is the same size after 10 blocks as after 100 (the rows carried, the histograms)."""

    def state_bytes(rows: int) -> int:
        episode = Episode(teleoperation(np.random.default_rng(6), rows, 30.0), np.arange(rows) / 30.0, None)
        metrics = SegmentQa("s", NAMES, np.full(6, 0.1), LOWER, UPPER)
        for start in range(0, rows, 1000):
            metrics.add(episode.values[start : start + 1000], episode.times[start : start + 1000] if episode.times is not None else None)
        return sum(value.nbytes for value in vars(metrics).values() if isinstance(value, np.ndarray)) + 8 * metrics.early_count

    assert state_bytes(10_000) == state_bytes(100_000)


@pytest.mark.parametrize("timeline", ["seconds", "ns", "fps"])
def test_block_boundaries_anywhere_give_identical_numbers(timeline: str) -> None:
    episode = rough_episode(np.random.default_rng(8), timeline)
    whole = feed(episode, episode.values.shape[0])
    assert feed(episode, 1) == whole
    assert feed(episode, 7) == whole
    assert feed(episode, 1000) == whole


def test_an_absolute_gap_and_the_nominal_step_without_fps() -> None:
    episode = rough_episode(np.random.default_rng(9), "seconds")
    qa = QaPlan(gap_seconds=0.05)
    assert_matches(feed(episode, 7, qa=qa), reference(episode, qa))
    assert feed(episode, 7).timing.nominal_step_s == pytest.approx(1 / 30, rel=0.1)


def test_a_short_segment_has_no_jerk_and_an_empty_one_no_numbers() -> None:
    two = feed(Episode(np.zeros((2, 6)), np.array([0.0, 0.1]), None), 1)
    assert two.rows == 2 and two.duration_s == pytest.approx(0.1)
    assert two.joints["j1"].p95_abs_jerk is None and two.joints["j1"].max_abs_velocity == 0.0
    empty = feed(Episode(np.zeros((0, 6)), np.zeros(0), None), 1)
    assert empty.rows == 0 and empty.duration_s is None and empty.timing.max_gap_s is None


def synthetic_dataset(fps: float, seconds: float, rng: np.random.Generator) -> list[Episode]:
    """Clean teleoperation episodes of slightly different lengths, with timestamps at 1/fps."""
    episodes = []
    for _ in range(12):
        rows = int(seconds * fps * rng.uniform(0.85, 1.15))
        episodes.append(Episode(teleoperation(rng, rows, fps), np.arange(rows) / fps, None))
    return episodes


def flags_of(episodes: list[Episode]) -> list[tuple[str, ...]]:
    metrics = [feed(episode, 1000, f"episode_{i}") for i, episode in enumerate(episodes)]
    return [tuple(flags) for flags in segment_flags(metrics, QA, ANGULAR)]


def test_clean_noisy_data_gets_no_flag() -> None:
    assert flags_of(synthetic_dataset(30.0, 20.0, np.random.default_rng(1))) == [()] * 12


def test_clean_noisy_data_at_1_khz_gets_no_spike() -> None:
    """Finite-difference jerk of noise grows as rate^3; the spike rule is relative to the dataset's own p95."""
    assert flags_of(synthetic_dataset(1000.0, 5.0, np.random.default_rng(2))) == [()] * 12


def test_each_planted_fault_gets_exactly_its_flag_on_exactly_its_segment() -> None:
    rng = np.random.default_rng(3)
    fps = 30.0
    episodes = synthetic_dataset(fps, 20.0, rng)
    spike = episodes[1].values.copy()
    spike[300, 2] += 40 * DEG  # a one-frame 40 deg jump
    episodes[1] = Episode(spike, episodes[1].times, None)
    rows = episodes[3].values.shape[0]
    episodes[3] = Episode(teleoperation(rng, rows, fps, moving=False), episodes[3].times, None)  # nothing moves
    long_rows = 3 * int(np.median([e.values.shape[0] for e in episodes]))
    episodes[5] = Episode(teleoperation(rng, long_rows, fps), np.arange(long_rows) / fps, None)  # 3x the median length
    keep = np.r_[0:200, 204 : episodes[7].values.shape[0]]  # 4 missing frames
    assert episodes[7].times is not None
    episodes[7] = Episode(episodes[7].values[keep], episodes[7].times[keep], None)
    times = episodes[9].times.copy() if episodes[9].times is not None else None
    assert times is not None
    times[250] = times[249] - 0.001  # a backwards timestamp
    episodes[9] = Episode(episodes[9].values, times, None)
    expected = [()] * 12
    expected[1], expected[3], expected[5], expected[7], expected[9] = (
        ("spike",),
        ("static",),
        ("length_outlier",),
        ("timestamp_gap",),
        ("timestamp_order",),
    )
    assert flags_of(episodes) == expected
    assert feed(episodes[1], 7).joints["j3"].max_jerk_row == 301  # the jump at row 300: its largest jerk ends at 301


def test_limits_nan_and_the_absolute_jerk_bound_are_flagged() -> None:
    rng = np.random.default_rng(4)
    episodes = synthetic_dataset(30.0, 20.0, rng)
    beyond = episodes[0].values.copy()
    beyond[10, 0] = 3.1
    episodes[0] = Episode(beyond, episodes[0].times, None)
    missing = episodes[2].values.copy()
    missing[20, 4] = np.nan
    episodes[2] = Episode(missing, episodes[2].times, None)
    metrics = [feed(episode, 1000, f"episode_{i}") for i, episode in enumerate(episodes)]
    flags = segment_flags(metrics, QA, ANGULAR)
    assert "limits" in flags[0] and flags[2] == ("nan",)
    bounded = QaPlan(spike_jerk=QA.bias.__class__(1.0, 1.0, "1 rad/s^3"))
    assert all("spike" in f for f in segment_flags(metrics, bounded, ANGULAR))
