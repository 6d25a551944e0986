"""Remote locations a config may name, and the rule of which ones it may: `s3://BUCKET/KEY` and
`hf://datasets/ORG/NAME[@REV][/PATH]`, each only under a prefix `URDF_PIPELINE_ALLOW_URLS` allows (security.md#fetching
lists what is refused). A config from a pull request must not make the runner fetch what whoever runs the tool did not
name, so the rule is checked on a URL's parsed parts before any request; as `confine.py` for local paths, a config
cannot widen it, only the environment can.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Literal

from ..confine import URL, is_remote
from ..errors import UserError, Where, shown

ALLOW_URLS_ENV = "URDF_PIPELINE_ALLOW_URLS"
SCHEMES = ("s3", "hf")
URL_LIMIT = 1024  # characters: S3 keys are at most 1024 bytes
SCHEME = URL  # `s3://`, `hf://`, and anything else a person might write as a URL (`https://`, `gs://`, `file://`)
BUCKET = re.compile(r"^[a-z0-9][a-z0-9.-]{1,61}[a-z0-9]$")  # S3's bucket names (no uppercase, no underscore)
HUB_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,95}$")  # an ORG or NAME on the Hub
HUB_ORGANISATION = re.compile(r"^hf://datasets/([A-Za-z0-9][A-Za-z0-9._-]{0,95})/?$")  # an allow entry: a whole organisation
REVISION = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._/-]{0,199}$")  # a branch, tag or commit sha


@dataclass(frozen=True)
class RemoteUrl:
    """A parsed remote location. S3: `bucket` and `key` (a prefix or pattern for a folder or glob). Hub: `repo`
    (`ORG/NAME`, a dataset repository), `revision` ("" when the URL pins none) and `key` (a path inside it)."""

    scheme: Literal["s3", "hf"]
    bucket: str  # S3 bucket; "" for the Hub
    repo: str  # Hub dataset ORG/NAME; "" for S3
    revision: str
    key: str

    @property
    def url(self) -> str:
        """The URL as the tool writes it (in messages, manifests and recordings): credentials never are part of it."""
        if self.scheme == "s3":
            return f"s3://{self.bucket}/{self.key}" if self.key else f"s3://{self.bucket}"
        at = f"@{self.revision}" if self.revision else ""
        return f"hf://datasets/{self.repo}{at}" + (f"/{self.key}" if self.key else "")

    def child_prefix(self, prefix: str) -> RemoteUrl:
        """The listing prefix `prefix/` in the same bucket or dataset ("" for all of it)."""
        return RemoteUrl(self.scheme, self.bucket, self.repo, self.revision, f"{prefix}/" if prefix else "")

    def with_revision(self, revision: str) -> RemoteUrl:
        return RemoteUrl(self.scheme, self.bucket, self.repo, revision, self.key)

    @property
    def name(self) -> str:
        """The last segment: the file's own name (its suffix says its kind to the readers)."""
        return self.key.rstrip("/").rsplit("/", 1)[-1] or self.repo.rsplit("/", 1)[-1] or self.bucket


def parse_url(text: str, where: Where | None = None, what: str = "location") -> RemoteUrl:
    """`text` as a RemoteUrl, or a UserError at `where` naming what is wrong and the forms that are right."""
    if len(text) > URL_LIMIT:
        raise UserError(f"{what} {shown(text)} is longer than {URL_LIMIT} characters", where)
    if any(ord(c) < 32 or ord(c) == 127 for c in text) or "\\" in text:
        raise UserError(f"{what} {shown(text)} holds a control character or a backslash; write the URL plainly", where)
    match = SCHEME.match(text) if is_remote(text) else None
    scheme = match.group(1).lower() if match else ""
    if scheme not in SCHEMES:
        raise UserError(
            f"{what} {shown(text)}: the scheme {scheme or 'none'}:// is not one urdf-pipeline reads; "
            "remote data is s3://BUCKET/KEY or hf://datasets/ORG/NAME@REVISION (a plain http(s) URL is never fetched)",
            where,
        )
    rest = text[len(scheme) + 3 :]
    if any(mark in rest for mark in ("?", "#", "%")):
        raise UserError(f"{what} {shown(text)}: a query, fragment or percent-escape is not part of a {scheme}:// location", where)
    return _parse_s3(text, rest, where, what) if scheme == "s3" else _parse_hub(text, rest, where, what)


def _segments_ok(parts: list[str]) -> bool:
    return all(part not in ("", ".", "..") for part in parts)


def _parse_s3(text: str, rest: str, where: Where | None, what: str) -> RemoteUrl:
    bucket, _, key = rest.partition("/")
    if not BUCKET.match(bucket):
        raise UserError(f"{what} {shown(text)}: {shown(bucket)!s} is not an S3 bucket name; write s3://BUCKET/KEY", where)
    segments = key.rstrip("/").split("/") if key.rstrip("/") else []
    if not _segments_ok(segments):
        raise UserError(f"{what} {shown(text)}: an empty, '.' or '..' segment in the key; write each folder once", where)
    return RemoteUrl("s3", bucket, "", "", key)


def _parse_hub(text: str, rest: str, where: Where | None, what: str) -> RemoteUrl:
    kind, _, rest = rest.partition("/")
    if kind != "datasets":
        raise UserError(f"{what} {shown(text)}: only Hub datasets are read; write hf://datasets/ORG/NAME@REVISION", where)
    org, _, rest = rest.partition("/")
    name_rev, _, key = rest.partition("/")
    name, at, revision = name_rev.partition("@")
    if not (HUB_NAME.match(org) and HUB_NAME.match(name)):
        raise UserError(f"{what} {shown(text)}: not a Hub dataset; write hf://datasets/ORG/NAME@REVISION", where)
    if at and not REVISION.match(revision):
        raise UserError(f"{what} {shown(text)}: {shown(revision)} is not a revision (a branch, tag or commit)", where)
    segments = key.rstrip("/").split("/") if key.rstrip("/") else []
    if not _segments_ok(segments) or ".." in revision.split("/"):
        raise UserError(f"{what} {shown(text)}: an empty, '.' or '..' segment in the path; write each folder once", where)
    return RemoteUrl("hf", "", f"{org}/{name}", revision, key)


@dataclass(frozen=True)
class AllowedPrefix:
    """One entry of URDF_PIPELINE_ALLOW_URLS, parsed as a URL is."""

    location: RemoteUrl

    def allows(self, url: RemoteUrl) -> bool:
        mine = self.location
        if mine.repo.endswith("/"):  # hf://datasets/ORG/: every dataset of the organisation
            return url.scheme == "hf" and url.repo.startswith(mine.repo)
        if (mine.scheme, mine.bucket, mine.repo) != (url.scheme, url.bucket, url.repo):
            return False
        if mine.revision and mine.revision != url.revision:
            return False
        prefix = mine.key
        if not prefix:
            return True
        if prefix.endswith("/"):
            return url.key.startswith(prefix)
        return url.key == prefix or url.key.startswith(prefix + "/")  # s3://b/data allows data/x, not data2/x


def allowed_prefixes() -> tuple[AllowedPrefix, ...]:
    """The environment's allowed prefixes; an entry that is no valid location is a UserError naming the variable."""
    text = os.environ.get(ALLOW_URLS_ENV, "")
    entries = [entry.strip() for entry in text.split(",") if entry.strip()]
    prefixes = []
    for entry in entries:
        organisation = HUB_ORGANISATION.match(entry)
        if organisation:
            prefixes.append(AllowedPrefix(RemoteUrl("hf", "", organisation.group(1) + "/", "", "")))
            continue
        try:
            prefixes.append(AllowedPrefix(parse_url(entry, None, f"{ALLOW_URLS_ENV} entry")))
        except UserError as exc:
            raise UserError(f"{exc.message} (in the environment, not the config)") from None
    return tuple(prefixes)


def check_allowed(url: RemoteUrl, where: Where | None, what: str = "location") -> RemoteUrl:
    """`url` when the environment allows it, else a UserError at `where` that names the variable to set: a config
    can name remote data, but only the person running the tool decides which."""
    prefixes = allowed_prefixes()
    if any(prefix.allows(url) for prefix in prefixes):
        return url
    named = ", ".join(shown(p.location.url, 80) for p in prefixes) or "nothing"
    raise UserError(
        f"{what} {shown(url.url)} is not under a location this run allows (it allows {named}); "
        f"whoever runs the tool may allow it: {ALLOW_URLS_ENV}={shown(url.url, 120)}",
        where,
    )


def remote_location(text: str, where: Where | None, what: str = "location") -> RemoteUrl:
    """A config's remote location, parsed and allowed, before any request is made."""
    return check_allowed(parse_url(text, where, what), where, what)
