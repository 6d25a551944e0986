"""Progress lines of one long segment: the share done and an ETA when the source's metadata gives the row count."""

from __future__ import annotations

from urdf_pipeline.progress import RowProgress


def test_a_known_row_count_gives_a_share_and_an_eta() -> None:
    progress = RowProgress("robot arm", total=1_000_000)
    progress.rows = 400_000
    assert progress.line(2.0) == "robot arm: 400,000 of 1,000,000 rows (40%, 200,000 rows/s, ETA 00:00:03)"


def test_more_rows_than_the_metadata_said_stop_at_100_percent() -> None:
    progress = RowProgress("robot arm", total=1_000)
    progress.rows = 1_500
    assert "1,000 of 1,000 rows (100%" in progress.line(1.0)


def test_an_unknown_row_count_gives_the_rate_only() -> None:
    progress = RowProgress("robot arm")
    progress.rows = 400_000
    assert progress.line(2.0) == "robot arm: 400,000 rows (200,000 rows/s)"
