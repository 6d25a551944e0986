"""S3 objects through boto3: what an object is (`head`), the objects under a prefix, a read-only seekable file over
ranged GETs (metadata without the data), whole downloads and uploads. Endpoint, region and credentials are the standard
chain's, never a config's, and a message names the URL and the endpoint's host, never a key (docs/remote.md: the
bounds). A GET carries `If-Match: ETAG`: an object changed after it was planned is an error (412), never read as the old.
"""

from __future__ import annotations

import io
import os
from concurrent.futures import ThreadPoolExecutor
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import urlsplit

from ..errors import UserError, Where, shown
from ..plan import RemoteObject
from .locations import RemoteUrl, parse_url

if TYPE_CHECKING:
    from botocore.client import BaseClient

CONNECT_SECONDS = 5.0
READ_SECONDS = 30.0
ATTEMPTS = 4  # botocore's standard mode: the first try and three retries, with exponential backoff
LIST_LIMIT = 1_000_000  # objects under one prefix: a bound on what a glob may list
READ_BLOCK = 1 << 20  # bytes a ranged read fetches at least (a footer and its metadata in one or two requests)
PART_BYTES = 16 << 20  # a download of a larger object comes in ranges of this size ...
PARTS = 4  # ... this many at a time


def client() -> BaseClient:
    """One S3 client per process and AWS environment (boto3 clients are thread-safe), configured from the environment
    by boto3 itself: a notebook that sets AWS_PROFILE between two runs gets a client of the new profile."""
    return _client(tuple(sorted((name, value) for name, value in os.environ.items() if name.startswith("AWS_"))))


@lru_cache(maxsize=4)
def _client(environment: tuple[tuple[str, str], ...]) -> BaseClient:
    try:
        import boto3
        from botocore.config import Config
    except ImportError:
        raise UserError("s3:// locations need boto3: pip install 'urdf-pipeline[s3]'") from None
    config = Config(
        connect_timeout=CONNECT_SECONDS,
        read_timeout=READ_SECONDS,
        retries={"total_max_attempts": ATTEMPTS, "mode": "standard"},  # botocore's `max_attempts` counts retries only
        user_agent_extra="urdf-pipeline",
    )
    return boto3.session.Session().client("s3", config=config)


def endpoint() -> str:
    """The endpoint's scheme and host, for messages (no user or password, even if the variable holds them)."""
    url = client().meta.endpoint_url
    parts = urlsplit(url)
    return f"{parts.scheme}://{parts.hostname}" + (f":{parts.port}" if parts.port else "")


def s3_error(exc: BaseException, url: str, where: Where | None, doing: str = "read") -> UserError:
    """What went wrong with `url`, in words that name the fix; the SDK's own text only where it carries no secret."""
    from botocore.exceptions import BotoCoreError, ClientError, NoCredentialsError

    target = shown(url, 200)
    if isinstance(exc, NoCredentialsError):
        return UserError(
            f"cannot {doing} {target}: no AWS credentials (set AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY, or "
            "AWS_PROFILE, or run where an instance role applies)",
            where,
        )
    if isinstance(exc, ClientError):
        error = exc.response.get("Error", {})
        code = str(error.get("Code", ""))
        status = exc.response.get("ResponseMetadata", {}).get("HTTPStatusCode")
        if code in ("403", "AccessDenied", "Forbidden") or status == 403:
            return UserError(f"cannot {doing} {target}: access denied (403) for this run's AWS credentials", where)
        if code == "NoSuchBucket":
            return UserError(f"cannot {doing} {target}: no such bucket", where)
        if code in ("404", "NoSuchKey", "NotFound") or status == 404:
            return UserError(f"cannot {doing} {target}: no such object (404)", where)
        if code in ("412", "PreconditionFailed") or status == 412:
            return UserError(
                f"{target} changed after it was planned (its ETag is no longer the planned one): "
                "run again to plan its new version; nothing was mixed",
                where,
            )
        return UserError(f"cannot {doing} {target}: {shown(code or status, 80)} from {endpoint()}", where)
    if isinstance(exc, BotoCoreError):
        return UserError(f"cannot {doing} {target}: {_transport_problem(exc)}", where)
    return UserError(f"cannot {doing} {target}: {shown(exc, 200)}", where)


def _transport_problem(exc: BaseException) -> str:
    """What went wrong between this machine and the endpoint, and what bounded it (botocore retried the request
    ATTEMPTS times in all; a transfer that broke off midway is not retried: `run` starts the object over)."""
    from botocore.exceptions import (
        ConnectionClosedError,
        ConnectionError,
        IncompleteReadError,
        ReadTimeoutError,
        ResponseStreamingError,
    )

    if isinstance(exc, ReadTimeoutError):
        return f"{endpoint()} did not answer within {READ_SECONDS:g} s ({ATTEMPTS} attempts); is it overloaded, or the network slow?"
    if isinstance(exc, ConnectionError):
        return (
            f"cannot connect to {endpoint()} ({ATTEMPTS} attempts, at most {CONNECT_SECONDS:g} s each): is it running, "
            "and does AWS_ENDPOINT_URL (or the profile's endpoint) name it?"
        )
    if isinstance(exc, ResponseStreamingError | IncompleteReadError | ConnectionClosedError):
        return (
            f"the connection to {endpoint()} broke off during the transfer ({shown(type(exc).__name__, 80)}): "
            "the endpoint stopped or the network dropped"
        )
    return f"{shown(type(exc).__name__, 80)} from {endpoint()} after {ATTEMPTS} attempts"


def _errors() -> tuple[type[BaseException], ...]:
    from botocore.exceptions import BotoCoreError, ClientError

    return (BotoCoreError, ClientError, OSError)


def _etag(value: Any) -> str:
    return str(value or "").strip('"')


def _head(url: RemoteUrl, where: Where | None) -> dict[str, Any]:
    try:
        return dict(client().head_object(Bucket=url.bucket, Key=url.key))
    except _errors() as exc:
        raise s3_error(exc, url.url, where) from None


def head(url: RemoteUrl, where: Where | None) -> RemoteObject:
    """What the object at `url` is now: its ETag and size (one HEAD request)."""
    answer = _head(url, where)
    return RemoteObject(url.url, _etag(answer.get("ETag")), int(answer.get("ContentLength", 0)))


def listing(prefix: RemoteUrl, where: Where | None) -> list[RemoteObject]:
    """Every object under `prefix` (its key up to the last `/`), in key order; at most LIST_LIMIT."""
    found: list[RemoteObject] = []
    try:
        pages = client().get_paginator("list_objects_v2").paginate(Bucket=prefix.bucket, Prefix=prefix.key)
        for page in pages:
            for entry in page.get("Contents", ()):
                found.append(RemoteObject(f"s3://{prefix.bucket}/{entry['Key']}", _etag(entry.get("ETag")), int(entry.get("Size", 0))))
            if len(found) > LIST_LIMIT:
                raise UserError(f"more than {LIST_LIMIT:,} objects under {shown(prefix.url)}; name a narrower prefix", where)
    except _errors() as exc:
        raise s3_error(exc, prefix.url, where, "list") from None
    return sorted(found, key=lambda o: o.url)


class OverBudget(UserError):
    """A metadata read through a `RangeFile` that needed more ranged GETs (or bytes) than its caller allowed: the
    caller reads the object otherwise (downloads it whole) or asks the config for what it would have read."""


class RangeFile(io.RawIOBase):
    """The object, read-only and seekable, each read one ranged GET pinned to its ETag: pyarrow reads a parquet
    footer, the mcap library an MCAP summary, h5py an HDF5 file's structure, through it, fetching only what they
    read. Wrap it in `io.BufferedReader(..., READ_BLOCK)` (see `open_range`) so small reads share a request.
    `max_requests` and `max_bytes` bound what it fetches: one GET more raises `OverBudget` before it is sent."""

    def __init__(self, remote: RemoteObject, where: Where | None, max_requests: int | None = None, max_bytes: int | None = None) -> None:
        super().__init__()
        self.remote = remote
        self.where = where
        self._url = parse_url(remote.url)
        self._position = 0
        self.requests = 0
        self.fetched = 0  # bytes received
        self.max_requests = max_requests
        self.max_bytes = max_bytes

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._position

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._position, io.SEEK_END: self.remote.size}[whence]
        self._position = max(0, base + offset)
        return self._position

    def readinto(self, buffer: Any) -> int:
        view = memoryview(buffer).cast("B")
        end = min(self.remote.size, self._position + len(view))
        if end <= self._position:
            return 0
        data = self._get(self._position, end - 1)
        view[: len(data)] = data
        self._position += len(data)
        return len(data)

    def _get(self, first: int, last: int) -> bytes:
        over_requests = self.max_requests is not None and self.requests >= self.max_requests
        if over_requests or (self.max_bytes is not None and self.fetched + last - first + 1 > self.max_bytes):
            budget = f"{self.max_requests} ranged requests" if over_requests else f"{self.max_bytes} bytes"
            raise OverBudget(
                f"reading the metadata of {shown(self.remote.url, 200)} takes more than {budget} "
                f"(read so far: {self.requests} requests, {self.fetched} bytes)",
                self.where,
            )
        self.requests += 1
        try:
            data = bytes(_ranged(self._url, self.remote, first, last)["Body"].read())
        except _errors() as exc:
            raise s3_error(exc, self.remote.url, self.where) from None
        self.fetched += len(data)
        return data


def open_range(
    remote: RemoteObject, where: Where | None, block: int = READ_BLOCK, max_requests: int | None = None, max_bytes: int | None = None
) -> io.BufferedReader:
    """A buffered, seekable reader of the object (see RangeFile), reading at least `block` bytes per request; its
    `raw` (the RangeFile) counts the requests and bytes."""
    return io.BufferedReader(RangeFile(remote, where, max_requests, max_bytes), block)


def download(remote: RemoteObject, target: Path, where: Where | None) -> None:
    """The whole object into `target` (created), only if its ETag is still the planned one: every GET carries
    `If-Match`. A large object comes in PART_BYTES ranges, PARTS at a time, each written at its offset."""
    url = parse_url(remote.url)
    parts = [(first, min(first + PART_BYTES, remote.size) - 1) for first in range(0, remote.size, PART_BYTES)]
    try:
        with open(target, "wb") as file:
            if len(parts) <= 1:
                answer = client().get_object(Bucket=url.bucket, Key=url.key, IfMatch=f'"{remote.version}"')
                for block in answer["Body"].iter_chunks(READ_BLOCK):
                    file.write(block)
            else:
                with ThreadPoolExecutor(PARTS, thread_name_prefix="s3-download") as pool:
                    list(pool.map(lambda part: _part(url, remote, part, file.fileno()), parts))
            file.flush()
            os.fsync(file.fileno())
    except _errors() as exc:
        raise s3_error(exc, remote.url, where) from None
    if target.stat().st_size != remote.size:
        raise UserError(f"{shown(remote.url, 200)}: {target.stat().st_size} bytes arrived, {remote.size} were planned", where)


def _ranged(url: RemoteUrl, remote: RemoteObject, first: int, last: int) -> Any:
    """One ranged GET of bytes `first`..`last`, only if the object's ETag is still the planned one."""
    return client().get_object(Bucket=url.bucket, Key=url.key, Range=f"bytes={first}-{last}", IfMatch=f'"{remote.version}"')


def _part(url: RemoteUrl, remote: RemoteObject, part: tuple[int, int], descriptor: int) -> None:
    offset = part[0]
    for block in _ranged(url, remote, *part)["Body"].iter_chunks(READ_BLOCK):
        os.pwrite(descriptor, block, offset)
        offset += len(block)


def upload(source: Path, url: RemoteUrl, where: Where | None, metadata: dict[str, str] | None = None) -> RemoteObject:
    """`source` uploaded to `url` (multipart when large: the object appears whole or not at all, never a part of it
    under its name), with `metadata` (`x-amz-meta-*`), and what it is now."""
    try:
        client().upload_file(os.fspath(source), url.bucket, url.key, ExtraArgs={"Metadata": metadata or {}})
    except _errors() as exc:
        raise s3_error(exc, url.url, where, "write") from None
    return head(url, where)


def metadata_of(url: RemoteUrl, where: Where | None) -> dict[str, str]:
    """The object's user metadata (`x-amz-meta-*`, lowercase keys): one HEAD."""
    return {str(k).lower(): str(v) for k, v in _head(url, where).get("Metadata", {}).items()}
