"""A dataset written to S3 (a real S3 endpoint: moto_server on 127.0.0.1): each recording staged, uploaded whole and
removed from the staging folder, the manifest last; a re-run compares the bucket's ETags and uploads nothing; a deleted
object is written again, alone; an object urdf-pipeline did not write is never replaced; a run stopped before its
manifest went up leaves objects the next run adopts by their metadata."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ..conftest import S3
from ..dataset_helpers import edit_config, recording_content, status_lines, store_ids


def _keys(s3: S3) -> list[str]:
    answer = s3.client().list_objects_v2(Bucket=s3.bucket)
    return sorted(entry["Key"] for entry in answer.get("Contents", []))


def _staged_recordings(tmp_path: Path) -> list[str]:
    return sorted(p.name for p in (tmp_path / "staging").rglob("*.rrd")) if (tmp_path / "staging").exists() else []


def test_a_dataset_goes_to_the_bucket_and_a_rerun_uploads_nothing(
    remote_dataset: Path, s3: S3, tmp_path: Path, examples_dir: Path, run_cli
) -> None:
    first = run_cli("run", str(remote_dataset), "--jobs", "2")
    assert first.code == 0, first.err
    keys = _keys(s3)
    episodes = [k for k in keys if k.startswith("so101/episode_")]
    assert len(episodes) >= 2 and "so101/model.rrd" in keys
    assert "so101/so101_dataset.manifest.json" in keys and "so101/so101_dataset.rbl" in keys
    assert first.out.split() == sorted(s3.url(k) for k in [*episodes, "so101/model.rrd"]) or set(first.out.split()) == {
        s3.url(k) for k in [*episodes, "so101/model.rrd"]
    }
    assert _staged_recordings(tmp_path) == [], "each recording is removed from the staging folder once uploaded"

    local = run_cli("run", str(examples_dir / "so101_dataset.yaml"), "--jobs", "2")  # the same dataset, to local files
    assert local.code == 0, local.err
    downloaded = tmp_path / "downloaded.rrd"
    s3.client().download_file(s3.bucket, episodes[0], str(downloaded))
    name = Path(episodes[0]).name
    assert store_ids(downloaded) == ("so101_dataset", name.removesuffix(".rrd"))
    assert recording_content(downloaded) == recording_content(examples_dir / "out" / "so101_dataset" / name)

    manifest = json.loads(s3.client().get_object(Bucket=s3.bucket, Key="so101/so101_dataset.manifest.json")["Body"].read())
    entry = next(e for e in manifest["segments"] if e["segment"] == name.removesuffix(".rrd"))
    assert entry["url"] == s3.url(episodes[0]) and entry["etag"]

    etags = {e["Key"]: e["ETag"] for e in s3.client().list_objects_v2(Bucket=s3.bucket)["Contents"]}
    again = run_cli("run", str(remote_dataset), "--jobs", "2")
    assert again.code == 0, again.err
    assert set(status_lines(again.err).values()) == {"skipped"}
    assert {e["Key"]: e["ETag"] for e in s3.client().list_objects_v2(Bucket=s3.bucket)["Contents"] if e["Key"].endswith(".rrd")} == {
        k: v for k, v in etags.items() if k.endswith(".rrd")
    }

    s3.client().delete_object(Bucket=s3.bucket, Key=episodes[1])  # gone from the bucket: written again, alone
    third = run_cli("run", str(remote_dataset), "--jobs", "1")
    assert third.code == 0, third.err
    statuses = status_lines(third.err)
    assert statuses[Path(episodes[1]).stem] == "written"
    assert [s for label, s in statuses.items() if label != Path(episodes[1]).stem] == ["skipped"] * (len(statuses) - 1)
    assert episodes[1] in _keys(s3)


def test_objects_of_a_run_whose_manifest_never_went_up_are_adopted(remote_dataset: Path, s3: S3, tmp_path: Path, run_cli) -> None:
    assert run_cli("run", str(remote_dataset), "--jobs", "1").code == 0
    s3.client().delete_object(Bucket=s3.bucket, Key="so101/so101_dataset.manifest.json")  # as if killed before it went up
    for manifest in (tmp_path / "staging").rglob("*.manifest.json"):
        manifest.unlink()
    again = run_cli("run", str(remote_dataset), "--jobs", "1")
    assert again.code == 0, again.err
    assert set(status_lines(again.err).values()) == {"skipped"}  # known by their content hash metadata: nothing rewritten
    assert "so101/so101_dataset.manifest.json" in _keys(s3)


def test_an_object_the_tool_did_not_write_is_never_replaced(remote_dataset: Path, s3: S3, tmp_path: Path, run_cli) -> None:
    s3.client().put_object(Bucket=s3.bucket, Key="so101/episode_000001.rrd", Body=b"somebody else's")
    refused = run_cli("run", str(remote_dataset), "--force")
    assert refused.code == 1
    assert "an object is there that urdf-pipeline did not write" in refused.err and s3.url("so101/episode_000001.rrd") in refused.err
    assert _keys(s3) == ["so101/episode_000001.rrd"], "nothing was computed or uploaded"
    assert s3.client().get_object(Bucket=s3.bucket, Key="so101/episode_000001.rrd")["Body"].read() == b"somebody else's"


def test_outputs_go_together(remote_dataset: Path, s3: S3, run_cli) -> None:
    edit_config(remote_dataset, lambda data: data["output"].update(model="out/model.rrd"))
    result = run_cli("validate", str(remote_dataset))
    assert result.code == 1 and "output.path is a URL but output.model is a local path" in result.err, result.err


def test_the_run_report_goes_to_the_bucket_with_the_urls(remote_dataset: Path, s3: S3, run_cli) -> None:
    result = run_cli("run", str(remote_dataset), "--jobs", "1", "--report", s3.url("reports/run.json"))
    assert result.code == 0, result.err
    report = json.loads(s3.client().get_object(Bucket=s3.bucket, Key="reports/run.json")["Body"].read())
    assert {r["output"] for r in report["results"]} >= {s3.url("so101/model.rrd"), s3.url("so101/episode_000000.rrd")}
    refused = run_cli("run", str(remote_dataset), "--report", "https://example.com/report.json")
    assert refused.code == 1 and "--report" in refused.err and "https:// is not one" in refused.err


def test_catalog_registration_sends_the_urls(remote_dataset: Path, s3: S3, run_cli) -> None:
    """`run --catalog` registers outputs in S3 by their s3:// URLs; Rerun's open-source server reads local files only
    and says so, named in one line (a catalog that reads S3 takes them)."""
    import rerun as rr

    pytest.importorskip("datafusion", reason="needs the catalog extra (rerun-sdk[catalog])")
    with rr.server.Server(host="127.0.0.1", port=0) as server:
        result = run_cli("run", str(remote_dataset), "--jobs", "1", "--catalog", server.url(), "--dataset", "so101")
    assert result.code == 1, result.err
    assert "refused model asset s3://" in result.err and "could not load URI: s3://" in result.err, result.err
    assert "Traceback" not in result.err


def test_credentials_never_reach_output_manifest_report_or_recordings(remote_dataset: Path, s3: S3, tmp_path: Path, run_cli) -> None:
    from ..s3_server import CREDENTIALS

    secrets = [CREDENTIALS["AWS_ACCESS_KEY_ID"], CREDENTIALS["AWS_SECRET_ACCESS_KEY"]]
    result = run_cli("run", str(remote_dataset), "--jobs", "2", "-v", "--report", str(tmp_path / "report.json"))
    assert result.code == 0, result.err
    failing = run_cli("run", str(remote_dataset.parent / "missing.yaml"))  # and an error, for good measure
    texts = [result.out, result.err, failing.err, (tmp_path / "report.json").read_text()]
    for key in _keys(s3):
        texts.append(s3.client().get_object(Bucket=s3.bucket, Key=key)["Body"].read().decode("latin-1"))
    for found in (tmp_path / "staging").rglob("*"):
        if found.is_file():
            texts.append(found.read_bytes().decode("latin-1"))
    assert not [secret for secret in secrets for text in texts if secret in text]
