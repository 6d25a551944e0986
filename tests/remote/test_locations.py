"""Which remote locations a config may name: the two schemes parsed strictly, every other one refused by name, and
only what URDF_PIPELINE_ALLOW_URLS allows (a prefix on segment boundaries; a config cannot widen it)."""

from __future__ import annotations

import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.remote import ALLOW_URLS_ENV, check_allowed, is_remote, parse_url, remote_location


def test_the_two_schemes_parse() -> None:
    s3 = parse_url("s3://robot-data/so101/episode_0.parquet")
    assert (s3.scheme, s3.bucket, s3.key, s3.name) == ("s3", "robot-data", "so101/episode_0.parquet", "episode_0.parquet")
    assert s3.url == "s3://robot-data/so101/episode_0.parquet"
    hub = parse_url("hf://datasets/lerobot/svla_so101_pickplace@v2.1/meta/info.json")
    assert (hub.scheme, hub.repo, hub.revision, hub.key) == ("hf", "lerobot/svla_so101_pickplace", "v2.1", "meta/info.json")
    assert parse_url("hf://datasets/org/name").revision == ""


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("http://169.254.169.254/latest/meta-data/", "http:// is not one urdf-pipeline reads"),
        ("https://example.com/data.parquet", "https:// is not one"),
        ("file:///etc/passwd", "file:// is not one"),
        ("gs://bucket/key", "gs:// is not one"),
        ("s3://Bad_Bucket/key", "not an S3 bucket name"),
        ("s3://bucket/a/../b", "'..' segment"),
        ("s3://bucket/a//b", "empty"),
        ("s3://bucket/a?x=1", "query"),
        ("s3://bucket/a%2F..", "percent"),
        ("s3://bucket/a\nb", "control character"),
        ("hf://models/org/name", "only Hub datasets"),
        ("hf://datasets/org", "not a Hub dataset"),
        ("hf://datasets/org/name@", "not a revision"),
    ],
)
def test_what_is_refused_before_any_request(text: str, says: str) -> None:
    assert is_remote(text)
    with pytest.raises(UserError) as caught:
        parse_url(text)
    assert says in caught.value.message


def test_a_plain_path_is_no_url() -> None:
    assert not is_remote("data/episode.parquet") and not is_remote("s3:data") and not is_remote("C:/data")


def test_only_what_the_environment_allows(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ALLOW_URLS_ENV, "s3://robot-data/so101, hf://datasets/lerobot/")
    assert remote_location("s3://robot-data/so101/ep.parquet", None).key == "so101/ep.parquet"
    assert remote_location("s3://robot-data/so101", None).key == "so101"
    assert remote_location("hf://datasets/lerobot/pusht@main", None).repo == "lerobot/pusht"
    for refused in ("s3://robot-data/so1010/ep.parquet", "s3://robot-data/other", "s3://other-bucket/so101/x", "hf://datasets/evil/pusht"):
        with pytest.raises(UserError) as caught:
            remote_location(refused, None, "parquet file")
        message = caught.value.message
        assert "is not under a location this run allows" in message and f"{ALLOW_URLS_ENV}=" in message, message


def test_nothing_is_allowed_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(ALLOW_URLS_ENV, raising=False)
    with pytest.raises(UserError, match="it allows nothing"):
        check_allowed(parse_url("s3://robot-data/x"), None)


def test_a_pinned_revision_in_the_allow_list_allows_only_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ALLOW_URLS_ENV, "hf://datasets/lerobot/pusht@v2.1")
    assert remote_location("hf://datasets/lerobot/pusht@v2.1/meta/info.json", None)
    with pytest.raises(UserError):
        remote_location("hf://datasets/lerobot/pusht@main", None)


def test_a_bad_allow_entry_names_the_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ALLOW_URLS_ENV, "https://anything")
    with pytest.raises(UserError, match=rf"{ALLOW_URLS_ENV} entry .*\(in the environment, not the config\)"):
        remote_location("s3://robot-data/x", None)
